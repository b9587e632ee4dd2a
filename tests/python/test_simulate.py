"""sinew.simulate against sinew-simulate: a clamped cantilever under a tip load (λ = PL²/EI = 3),
the same equilibrium to 1e-9, and the elastica's tip deflection.

Run by ctest (python_module) with PYTHONPATH=<build>/python and SINEW_BINARY_DIR=<build>.
"""
import json
import os
import subprocess

import numpy as np
import pytest

import sinew

BIN = os.path.join(os.environ.get("SINEW_BINARY_DIR", "build/release"), "tools")


def cantilever(elements=20, load=3.0):
    return {"nodes": [[i / elements, 0.0] for i in range(elements + 1)],
            "fixed": [{"node": 0, "dofs": ["ux", "uy", "theta"]}],
            "material": {"E": 1e6, "G": 1e6, "A": 1.0, "I": 1e-6},
            "loads": [{"node": elements, "f": [0.0, -load, 0.0]}]}


def test_same_equilibrium_as_sinew_simulate(tmp_path):
    beam = cantilever()
    (tmp_path / "beam.json").write_text(json.dumps(beam))
    subprocess.run([os.path.join(BIN, "sinew-simulate"), "--beam", str(tmp_path / "beam.json"),
                    "--out", str(tmp_path / "out.json"), "--quiet"], check=True)
    want = json.load(open(tmp_path / "out.json"))
    got = sinew.simulate(beam)
    assert got["converged"] and got["status"] == want["status"]
    np.testing.assert_allclose(got["nodes"], np.asarray(want["nodes"]), rtol=0, atol=1e-9)
    from_file = sinew.simulate(str(tmp_path / "beam.json"))
    np.testing.assert_allclose(from_file["nodes"], got["nodes"], rtol=0, atol=0)
    # The elastica at λ = 3 (Bisshopp & Drucker 1945; Mattiasson 1981; ../shared/reference/
    # beam_benchmarks.md): v/L 0.603253, (L − x)/L 0.254420, θ 0.986017; 20 elements are within 1e-3.
    tip = got["nodes"][-1]
    assert -tip[1] == pytest.approx(0.603253, abs=1e-3)
    assert 1.0 - tip[0] == pytest.approx(0.254420, abs=1e-3)
    assert -tip[2] == pytest.approx(0.986017, abs=1e-3)


def test_bad_beam_raises_with_the_field_named():
    beam = cantilever()
    beam["fixed"] = []
    with pytest.raises(ValueError, match="rigid motion"):
        sinew.simulate(beam)
