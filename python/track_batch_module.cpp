// The Python module `sinew._sinew_batch`: sinew-track --batch as a library call, for
// sinew.track_batch() (python/sinew/__init__.py), which returns its summary as a pandas DataFrame.
// Bad input raises ValueError with the one-line message sinew-track --batch prints.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <optional>
#include <string>
#include <vector>

#include "tools/io/json_file.hpp"
#include "tools/track/batch.hpp"

namespace py = pybind11;
using namespace sinew;

namespace {

// The batch of a manifest file (`path`) or of a manifest's JSON text (a dict, dumped by the
// caller; its relative names are relative to the current folder). Returns (exit status, rows).
py::tuple track_batch(const std::optional<std::string>& path,
                      const std::optional<std::string>& text, int jobs,
                      std::optional<std::size_t> task, bool gather, bool quiet) {
  if (jobs < 1) throw py::value_error("jobs = " + std::to_string(jobs) + " must be at least 1");
  tools::TrackBatchManifest manifest;
  try {
    if (path) {
      manifest = tools::read_track_batch_manifest(*path);
    } else {
      nlohmann::json doc;
      try {
        doc = nlohmann::json::parse(text.value_or(""));
      } catch (const nlohmann::json::exception& e) {
        throw tools::InputError(std::string("<dict>: not JSON: ") + e.what());
      }
      manifest = tools::parse_track_batch_manifest(doc, "<dict>");
    }
    if (task && *task >= manifest.videos.size()) {
      throw tools::InputError(manifest.path + ": task " + std::to_string(*task) +
                              " is not a video: the manifest has " +
                              std::to_string(manifest.videos.size()));
    }
  } catch (const tools::InputError& e) {
    throw py::value_error(e.what());
  }
  tools::TrackBatchOptions options;
  options.jobs = jobs;
  options.task = task;
  options.gather = gather;
  options.quiet = quiet;
  std::vector<tools::TrackBatchRow> rows;
  int status = 0;
  {
    py::gil_scoped_release release;  // the children run C++ only
    status = tools::run_track_batch(manifest, options, &rows);
  }
  py::list out;
  for (const tools::TrackBatchRow& r : rows) {
    out.append(py::dict(py::arg("video") = r.video, py::arg("out") = r.out_dir,
                        py::arg("frames") = r.frames, py::arg("whiskers") = r.whiskers,
                        py::arg("lost_fraction") = r.lost_fraction,
                        py::arg("contact_frames") = r.contact_frames,
                        py::arg("wall_seconds") = r.wall_seconds, py::arg("status") = r.status));
  }
  return py::make_tuple(status, out);
}

}  // namespace

PYBIND11_MODULE(_sinew_batch, m) {
  m.doc() = "sinew-track --batch as a library call (see sinew.track_batch)";
  m.def("track_batch", &track_batch, py::arg("path"), py::arg("text"), py::arg("jobs") = 1,
        py::arg("task") = std::nullopt, py::arg("gather") = false, py::arg("quiet") = true,
        "(exit status, summary rows as dicts) of sinew-track --batch on a manifest file (path) "
        "or a manifest's JSON text");
}
