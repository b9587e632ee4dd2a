// sinew-separate: removes the inter-penetration of two registered neighbouring organs (seed 003
// §4.1.4, offline/separation/interpenetration.hpp) and writes
//   OUTDIR/a_separated.vtu, b_separated.vtu  the two tet meshes after separation, with per-tet
//                                            "displacement" (largest displacement of its four
//                                            vertices, mesh units) as cell data (ParaView)
//   OUTDIR/a_surface.obj, b_surface.obj      their boundary surfaces (MeshLab, 3D Slicer)
//   OUTDIR/report.json                       inputs, options and the summary: penetrating vertices
//                                            before and after, depths, active tets, displacement
//
//   sinew-separate A B --out OUTDIR [--ring N] [--margin F] [--quiet]
//
// A and B are tet meshes (.vtu as sinew-register writes result.vtu, .mesh, .veg, .node/.ele) in
// the same units. Meshes that do not overlap are not an error: the outputs are the inputs and the
// report says 0 penetrations. For a third organ touching the first two, run it against each of
// them in turn (or against their union), as §4.1.4 does.
// Exit status: 0 separated (or nothing to separate); 1 outputs written but vertices are still
// inside the other mesh (report.json says why); 2 bad input or usage (one line on stderr naming
// the file; OUTDIR is not created).
#include <fmt/core.h>
#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "offline/io/surface_mesh_io.hpp"
#include "offline/io/tet_mesh_io.hpp"
#include "offline/meshing/surface_closest_point.hpp"
#include "offline/separation/interpenetration.hpp"
#include "tools/io/json_file.hpp"

namespace {

using namespace sinew;
namespace fs = std::filesystem;

struct Request {
  std::string a_path, b_path, out_dir;
  int ring_size = 5;
  std::optional<double> margin;
  bool quiet = false;
};

offline::TetMesh read_mesh(const std::string& path) {
  offline::TetMeshReadResult r = offline::read_tet_mesh(path);
  if (!r.ok()) throw tools::InputError(r.error);
  return std::move(*r.mesh);
}

/// The boundary surface of a tet mesh with only the vertices it uses.
offline::io::SurfaceMesh boundary_surface(const offline::TetMesh& mesh, const std::string& path) {
  offline::BoundaryCheck check;
  const auto boundary = offline::BoundarySurface::extract(mesh.vertices.rows(), mesh.tets, &check);
  if (!boundary) throw tools::InputError(path + ": tet mesh boundary: " + check.message());
  const std::vector<int>& used = boundary->vertices();
  std::vector<int> local(static_cast<std::size_t>(mesh.vertices.rows()), -1);
  offline::io::SurfaceMesh surface;
  surface.vertices.resize(static_cast<Eigen::Index>(used.size()), 3);
  for (std::size_t i = 0; i < used.size(); ++i) {
    local[static_cast<std::size_t>(used[i])] = static_cast<int>(i);
    surface.vertices.row(static_cast<Eigen::Index>(i)) = mesh.vertices.row(used[i]);
  }
  const auto& triangles = boundary->triangles();
  surface.triangles.resize(triangles.rows(), 3);
  for (Eigen::Index f = 0; f < triangles.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      surface.triangles(f, k) = local[static_cast<std::size_t>(triangles(f, k))];
  return surface;
}

/// Per tet: the largest displacement of its four vertices.
Eigen::VectorXd tet_displacements(const offline::TetMesh& before, const offline::TetMesh& after) {
  const Eigen::VectorXd vertex = (after.vertices - before.vertices).rowwise().norm();
  Eigen::VectorXd d(before.tets.rows());
  for (Eigen::Index t = 0; t < before.tets.rows(); ++t) {
    d[t] = 0.0;
    for (int k = 0; k < 4; ++k) d[t] = std::max(d[t], vertex[before.tets(t, k)]);
  }
  return d;
}

nlohmann::json summary_json(const offline::InterpenetrationSummary& s) {
  return {{"status", offline::to_string(s.status)},
          {"message", s.message},
          {"converged", s.converged()},
          {"penetrating_a_in_b_before", s.penetrating_a_before},
          {"penetrating_b_in_a_before", s.penetrating_b_before},
          {"penetrating_a_in_b_after", s.penetrating_a_after},
          {"penetrating_b_in_a_after", s.penetrating_b_after},
          {"max_depth_before", s.max_depth_before},
          {"max_depth_after", s.max_depth_after},
          {"active_tets_a", s.active_tets_a},
          {"active_tets_b", s.active_tets_b},
          {"free_vertices", s.free_vertices},
          {"vertices_moved", s.vertices_moved},
          {"max_displacement", s.max_displacement},
          {"rounds", s.iterations},
          {"newton_iterations", s.newton_iterations},
          {"mean_edge_length", s.mean_edge_length},
          {"margin", s.margin},
          {"seconds", s.seconds},
          {"detection_seconds", s.detection_seconds}};
}

int run(const Request& request) {
  const auto log = [&](const std::string& line) {
    if (!request.quiet) std::cout << line << std::endl;
  };
  offline::InterpenetrationOptions options;
  options.ring_size = request.ring_size;
  if (request.margin) options.contact_margin = *request.margin;
  if (auto error = options.validate()) throw tools::InputError(*error);

  const offline::TetMesh a0 = read_mesh(request.a_path);
  log(fmt::format("read {}: {} vertices, {} tets", request.a_path, a0.vertices.rows(),
                  a0.tets.rows()));
  const offline::TetMesh b0 = read_mesh(request.b_path);
  log(fmt::format("read {}: {} vertices, {} tets", request.b_path, b0.vertices.rows(),
                  b0.tets.rows()));
  // The boundaries are needed for the outputs: check them before anything is written.
  boundary_surface(a0, request.a_path);
  boundary_surface(b0, request.b_path);

  offline::TetMesh a = a0, b = b0;
  const offline::InterpenetrationSummary summary = offline::remove_interpenetration(a, b, options);
  if (summary.status == offline::InterpenetrationStatus::kInvalidInput)
    throw tools::InputError(request.a_path + ", " + request.b_path + ": " + summary.message);
  log(fmt::format("penetrating boundary vertices: {} of A in B, {} of B in A (max depth {:.4g})",
                  summary.penetrating_a_before, summary.penetrating_b_before,
                  summary.max_depth_before));
  log(summary.brief_report());

  // Outputs: OUTDIR is created only now that every input has been checked.
  const fs::path dir(request.out_dir);
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw tools::InputError(request.out_dir + ": exists and is not a folder");
  const bool created = !fs::exists(dir, ec);
  fs::create_directories(dir, ec);
  if (ec)
    throw tools::InputError(request.out_dir + ": cannot create folder (" + ec.message() + ")");
  try {
    std::vector<std::string> written;
    std::string error;
    const auto write_mesh = [&](const char* name, const offline::TetMesh& before,
                                const offline::TetMesh& after) {
      const std::string path = (dir / name).string();
      if (!offline::write_vtu(path, after, {{"displacement", tet_displacements(before, after)}},
                              &error))
        throw tools::InputError(error);
      written.push_back(path);
    };
    const auto write_surface = [&](const char* name, const offline::TetMesh& mesh,
                                   const std::string& input) {
      const std::string path = (dir / name).string();
      if (!offline::io::write_obj(path, boundary_surface(mesh, input), &error))
        throw tools::InputError(error);
      written.push_back(path);
    };
    write_mesh("a_separated.vtu", a0, a);
    write_mesh("b_separated.vtu", b0, b);
    write_surface("a_surface.obj", a, request.a_path);
    write_surface("b_surface.obj", b, request.b_path);

    nlohmann::json report;
    report["tool"] = "sinew-separate";
    report["inputs"] = {
        {"a",
         {{"file", request.a_path}, {"vertices", a0.vertices.rows()}, {"tets", a0.tets.rows()}}},
        {"b",
         {{"file", request.b_path}, {"vertices", b0.vertices.rows()}, {"tets", b0.tets.rows()}}}};
    report["options"] = {{"ring_size", options.ring_size},
                         {"contact_margin", options.contact_margin},
                         {"penalty_stiffness", options.penalty_stiffness},
                         {"max_iterations", options.max_iterations},
                         {"youngs_modulus", options.material.youngs_modulus},
                         {"poisson_ratio", options.material.poisson_ratio}};
    report["summary"] = summary_json(summary);
    const std::string report_path = (dir / "report.json").string();
    nlohmann::json outputs = written;
    outputs.push_back(report_path);
    report["outputs"] = outputs;
    tools::write_json_file(report_path, report);
    written.push_back(report_path);
    for (const auto& path : written) log("wrote " + path);
  } catch (...) {
    if (created) fs::remove_all(dir, ec);
    throw;
  }
  return summary.converged() ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Removes the inter-penetration of two registered neighbouring organs by a local FEM contact "
      "solve (Sinew)"};
  Request request;
  app.add_option("A", request.a_path, "first tet mesh (.vtu, .mesh, .veg, .node/.ele)")->required();
  app.add_option("B", request.b_path, "second tet mesh, same units")->required();
  app.add_option("--out", request.out_dir, "output folder (created)")->required();
  app.add_option("--ring", request.ring_size,
                 "rings of face-adjacent tets around the collision that may move (default 5)")
      ->check(CLI::Range(0, 1000));
  app.add_option("--margin", request.margin,
                 "gap left between the surfaces, fraction of the mean edge length (default 0.01)");
  app.add_flag("--quiet", request.quiet, "print nothing but errors");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    return run(request);
  } catch (const std::exception& e) {
    std::cerr << "sinew-separate: " << e.what() << "\n";
    return 2;
  }
}
