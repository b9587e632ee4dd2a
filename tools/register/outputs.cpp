#include "tools/register/outputs.hpp"

#include <algorithm>
#include <cctype>
#include <system_error>

#include "offline/io/tet_mesh_io.hpp"
#include "offline/registration/transfer.hpp"
#include "tools/io/json_file.hpp"
#include "tools/label/slice_pictures.hpp"
#include "tools/register/plots.hpp"

namespace sinew::tools {
namespace {

namespace fs = std::filesystem;

nlohmann::json mesher_json(const offline::TetMesherSummary& s) {
  nlohmann::json j;
  j["status"] = offline::to_string(s.status);
  j["vertices"] = s.num_vertices;
  j["tets"] = s.num_tets;
  j["boundary_faces"] = s.num_boundary_faces;
  j["input_inward_oriented"] = s.input_inward_oriented;
  j["flipped_tets"] = s.flipped_tets;
  if (s.min_dihedral_degrees) j["min_dihedral_degrees"] = *s.min_dihedral_degrees;
  if (s.max_dihedral_degrees) j["max_dihedral_degrees"] = *s.max_dihedral_degrees;
  if (s.min_radius_ratio) j["min_radius_ratio"] = *s.min_radius_ratio;
  if (s.mean_radius_ratio) j["mean_radius_ratio"] = *s.mean_radius_ratio;
  j["time_limit_reached"] = s.time_limit_reached;
  j["seconds"] = s.seconds;
  return j;
}

nlohmann::json quality_json(const offline::TetMeshQuality& q) {
  return nlohmann::json{{"min_dihedral_degrees", q.min_dihedral_degrees},
                        {"max_dihedral_degrees", q.max_dihedral_degrees},
                        {"min_radius_ratio", q.min_radius_ratio},
                        {"mean_radius_ratio", q.mean_radius_ratio},
                        {"inverted_tets", q.inverted_tets}};
}

nlohmann::json inputs_json(const offline::RegistrationCase& c, const offline::CaseInputSummary& s) {
  nlohmann::json inputs;
  inputs["template"] = c.template_path;
  if (s.template_triangles) inputs["template_triangles"] = *s.template_triangles;
  inputs["template_vertices"] = s.template_vertices;
  inputs["bounding_box_diagonal"] = s.bounding_box_diagonal;
  inputs["attachments"] = c.attachments.size();
  inputs["landmarks"] = c.landmarks.size();
  inputs["icp_markers"] = c.icp_markers.rows();
  if (!c.coordinate_system.empty()) inputs["coordinate_system"] = c.coordinate_system;
  inputs["notes"] = c.notes;
  if (s.mesher) inputs["mesher"] = mesher_json(*s.mesher);
  inputs["tet_vertices"] = s.tet_vertices;
  inputs["tets"] = s.tets;
  inputs["embedding_max_distance"] = s.embedding_max_distance;
  inputs["surface_embedding_max_distance"] = s.surface_embedding_max_distance;
  return inputs;
}

nlohmann::json iterations_json(const std::vector<offline::GaussNewtonIteration>& list,
                               double scale) {
  nlohmann::json iterations = nlohmann::json::array();
  for (const offline::GaussNewtonIteration& it : list) {
    iterations.push_back({{"stage", offline::to_string(it.stage)},
                          {"iteration", it.iteration},
                          {"objective", it.objective},
                          {"objective_before", it.objective_before},
                          {"step", it.step},
                          {"marker_error_mean", it.marker_error_mean * scale},
                          {"marker_error_max", it.marker_error_max * scale},
                          {"equilibrium_solves", it.equilibrium_solves},
                          {"predicted_decrease", it.predicted_decrease},
                          {"clamped_tets", it.clamped_tets},
                          {"damping", it.damping},
                          {"projected_search", it.projected_search},
                          {"inverted_equilibrium", it.inverted_equilibrium},
                          {"held_tets", it.held_tets},
                          {"held_by_elimination", it.held_by_elimination},
                          {"jacobian_seconds", it.jacobian_seconds},
                          {"woodbury_seconds", it.woodbury_seconds},
                          {"line_search_seconds", it.line_search_seconds},
                          {"seconds", it.seconds}});
  }
  return iterations;
}

nlohmann::json coverage_json(const offline::RegisteredShape& shape, double scale) {
  const offline::MarkerCoverage& coverage = shape.coverage;
  const Eigen::RowVector3d farthest = shape.mesh.vertices.row(coverage.farthest_vertex);
  const Eigen::RowVector3d weakest = shape.mesh.vertices.row(coverage.weakest_vertex);
  return {{"nominal_spacing", coverage.nominal_spacing * scale},
          {"uncovered_spacings", offline::MarkerCoverageOptions{}.uncovered_spacings},
          {"max_distance", coverage.max_distance * scale},
          {"max_distance_spacings", coverage.max_distance / coverage.nominal_spacing},
          {"farthest_point", {farthest.x(), farthest.y(), farthest.z()}},
          {"uncovered_area_fraction", coverage.uncovered_area_fraction},
          {"pinning_threshold", coverage.pinning_threshold},
          {"min_pinning", coverage.min_pinning},
          {"weakest_point", {weakest.x(), weakest.y(), weakest.z()}},
          {"weakly_pinned_area_fraction", coverage.weakly_pinned_area_fraction}};
}

// The deformed surface in OBJ, and in the template's own format for the tools that read it.
void write_surfaces(const RegisterOutputs& out, const offline::RegistrationCase& c,
                    const offline::io::SurfaceMesh& deformed, std::vector<std::string>& written) {
  std::string error;
  if (!offline::io::write_obj(out.surface().string(), deformed, &error))
    throw std::runtime_error(error);
  written.push_back(out.surface().string());
  std::string extension = fs::path(c.template_path).extension().string();
  for (char& ch : extension) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (!c.template_is_tet_mesh &&
      (extension == ".off" || extension == ".stl" || extension == ".ply")) {
    const fs::path same = out.dir / ("result_surface" + extension);
    if (!offline::io::write_surface_mesh(same.string(), deformed, &error))
      throw std::runtime_error(error);
    written.push_back(same.string());
  }
}

void write_vtu(const RegisterOutputs& out, const offline::RegisteredShape& shape, double scale) {
  std::string error;
  const offline::MarkerCoverage& coverage = shape.coverage;
  if (!offline::write_vtu_fields(
          out.vtu().string(), shape.mesh,
          {{"det_Fp", shape.det_Fp},
           {"Fp", shape.Fp},
           {"principal_stretches", shape.principal_stretches},
           {"stretch_ratio", shape.stretch_ratio}},
          {{"distance_to_nearest_marker", coverage.distance * scale},
           {"marker_pinning", coverage.pinning / coverage.pinning_threshold}},
          &error))
    throw std::runtime_error(error);
}

// Fig. 18: the result's cross-sections over the scan.
nlohmann::json write_slices(const RegisterOutputs& out, const offline::RegistrationCase& c,
                            const offline::io::SurfaceMesh& deformed, const ScanImages& scan,
                            std::vector<std::string>& written, const Log& log) {
  const std::string unit = offline::to_string(c.units);
  SlicePictureOptions slice_options;
  slice_options.count = c.scan_image->slices;
  slice_options.label = c.scan_image->label;
  slice_options.window_low = c.scan_image->window_low;
  slice_options.window_high = c.scan_image->window_high;
  nlohmann::json slices = nlohmann::json::array();
  for (const SlicePicture& picture :
       write_slice_pictures(*scan.image, scan.mask ? &*scan.mask : nullptr, deformed,
                            (out.dir / "slices").string(), slice_options)) {
    nlohmann::json entry = {{"file", picture.file}, {"k", picture.k}};
    if (picture.mean_distance) {
      entry["mean_distance_to_mask_outline"] = *picture.mean_distance;
      log.line("slice k = {}: cross-section {:.3g} {} from the mask's outline on average",
               picture.k, *picture.mean_distance, unit.empty() ? "units" : unit);
    }
    slices.push_back(entry);
    written.push_back(picture.file);
  }
  return slices;
}

}  // namespace

void prepare_output_dir(const RegisterOutputs& out, const offline::RegistrationCase& c) {
  std::error_code ec;
  if (fs::exists(out.dir, ec) && !fs::is_directory(out.dir, ec))
    throw InputError(out.dir.string() + ": exists and is not a folder");
  fs::create_directories(out.dir, ec);
  if (ec) throw InputError(out.dir.string() + ": cannot create folder (" + ec.message() + ")");
  const fs::path probe = out.dir / ".sinew-register-probe";
  std::FILE* f = std::fopen(probe.c_str(), "wb");
  if (f == nullptr) throw InputError(out.dir.string() + ": folder is not writable");
  std::fclose(f);
  fs::remove(probe, ec);
  for (const fs::path& stale :
       {out.report(), out.surface(), out.vtu(), out.dir / "result_surface.off",
        out.dir / "result_surface.stl", out.dir / "result_surface.ply",
        out.dir / "marker_errors.png", out.dir / "convergence.png"})
    fs::remove(stale, ec);
  for (const std::string& transferred : c.transfer_paths)
    fs::remove(out.dir / ("transfer_" + fs::path(transferred).filename().string()), ec);
  fs::remove_all(out.dir / "slices", ec);
}

std::optional<offline::io::SurfaceMesh> read_truth(const std::string& file,
                                                   const std::string& given_as, const Log& log) {
  if (file.empty()) return std::nullopt;
  offline::io::SurfaceMeshReadResult r = offline::io::read_surface_mesh(file);
  if (!r.ok()) throw InputError(r.error);
  log.line("truth: {}, {} vertices, {} triangles", given_as, r.mesh->vertices.rows(),
           r.mesh->triangles.rows());
  return std::move(*r.mesh);
}

ScanImages read_scan_images(const offline::RegistrationCase& c, const Log& log) {
  ScanImages scan;
  if (!c.scan_image) return scan;
  auto read_image = [&](const std::string& path) {
    offline::io::VolumeImageReadResult r = offline::io::read_volume_image(path);
    if (!r.image) throw InputError(r.error);
    return std::move(*r.image);
  };
  scan.image = read_image(c.scan_image->image);
  if (!c.scan_image->mask.empty()) {
    scan.mask = read_image(c.scan_image->mask);
    if (scan.mask->size != scan.image->size) {
      throw InputError(c.scan_image->mask + ": its voxel grid differs from " + c.scan_image->image +
                       "'s");
    }
  }
  log.line("scan image: {}, {} x {} x {} voxels{}", c.scan_image->image, scan.image->size.x(),
           scan.image->size.y(), scan.image->size.z(),
           scan.mask ? ", mask " + c.scan_image->mask : std::string());
  return scan;
}

nlohmann::json registration_report(const offline::RegistrationCase& c,
                                   const offline::RegisterCaseResult& r,
                                   const std::string& case_path, int resumes) {
  const offline::PreparedCase& p = r.problem;
  const offline::GaussNewtonOptions& options = p.options;
  const offline::GaussNewtonSummary& summary = r.registration.summary;
  const double scale = p.frame.scale;
  const std::string unit = offline::to_string(c.units);
  nlohmann::json report;
  report["tool"] = "sinew-register";
  report["case"] = case_path;
  report["resumes"] = resumes;
  report["length_unit"] = unit.empty() ? "template units" : unit;
  report["inputs"] = inputs_json(c, r.inputs);
  report["mode"] = p.free_object ? "free" : "attached";
  report["options"] = {{"alpha", options.alpha},
                       {"beta", options.beta},
                       {"attachment_stiffness", p.attachment_stiffness},
                       {"max_iterations_per_stage", options.max_iterations_per_stage},
                       {"max_marker_error", p.max_marker_error},
                       {"min_step", options.min_step},
                       {"icp_weight_ramp", options.icp_weight_ramp},
                       {"icp_no_progress_iterations", options.icp_no_progress_iterations},
                       {"cholesky", offline::to_string(c.solver.cholesky)},
                       {"mesh_cell_size_fraction", c.mesh.cell_size_fraction}};
  report["iterations"] = iterations_json(summary.iterations, scale);
  report["termination"] = offline::to_string(summary.termination);
  report["message"] = summary.message;
  report["usable"] = summary.usable();
  report["final"] = {
      {"stage", summary.iterations.empty() ? std::string("none")
                                           : offline::to_string(summary.iterations.back().stage)},
      {"objective", summary.final_objective},
      {"initial_objective", summary.initial_objective},
      {"marker_error_mean", summary.marker_error_mean * scale},
      {"marker_error_max", summary.marker_error_max * scale}};
  if (r.landmark_errors) {
    report["final"]["landmark_error_mean"] = r.landmark_errors->mean;
    report["final"]["landmark_error_max"] = r.landmark_errors->max;
  }
  if (r.shape) {
    report["coverage"] = coverage_json(*r.shape, scale);
    report["mesh_quality"] = {{"template", quality_json(r.shape->template_quality)},
                              {"result", quality_json(r.shape->result_quality)}};
  }
  return report;
}

nlohmann::json truth_report(const offline::io::SurfaceMesh& result,
                            const offline::io::SurfaceMesh& truth, const std::string& truth_path,
                            double diagonal, const std::string& unit, const Log& log) {
  const offline::TruthDistances d = offline::truth_distances(result, truth);
  const double farthest = std::max(d.result_to_truth.max, d.truth_to_result.max);
  const std::string u = unit.empty() ? "" : " " + unit;
  log.line(
      "truth: result vertices to {} mean {:.4g} max {:.4g}{}; its vertices to the result "
      "mean {:.4g} max {:.4g}{}; worst {:.2f}% of the diagonal",
      truth_path, d.result_to_truth.mean, d.result_to_truth.max, u, d.truth_to_result.mean,
      d.truth_to_result.max, u, 100 * farthest / diagonal);
  log.line(
      "truth: symmetric surface distance {:.4g}{} (mean over {} area-uniform samples on each "
      "surface: result to truth {:.4g}, truth to result {:.4g}{})",
      d.symmetric_mean_area_sampled, u, d.samples_per_surface, d.result_samples_to_truth.mean,
      d.truth_samples_to_result.mean, u);
  return {{"surface", truth_path},
          {"symmetric_mean_area_sampled", d.symmetric_mean_area_sampled},
          {"samples_per_surface", d.samples_per_surface},
          {"result_samples_to_truth_mean", d.result_samples_to_truth.mean},
          {"result_samples_to_truth_max", d.result_samples_to_truth.max},
          {"truth_samples_to_result_mean", d.truth_samples_to_result.mean},
          {"truth_samples_to_result_max", d.truth_samples_to_result.max},
          {"result_to_truth_mean", d.result_to_truth.mean},
          {"result_to_truth_max", d.result_to_truth.max},
          {"truth_to_result_mean", d.truth_to_result.mean},
          {"truth_to_result_max", d.truth_to_result.max},
          {"max_fraction_of_diagonal", farthest / diagonal}};
}

std::vector<std::string> write_result_files(const RegisterOutputs& out,
                                            const offline::RegistrationCase& c,
                                            const offline::RegisterCaseResult& r,
                                            const ScanImages& scan, nlohmann::json& report,
                                            const Log& log) {
  std::vector<std::string> written;
  if (!r.shape) return written;
  const offline::RegisteredShape& shape = *r.shape;
  const double scale = r.problem.frame.scale;
  write_surfaces(out, c, shape.surface, written);
  write_vtu(out, shape, scale);
  written.push_back(out.vtu().string());
  for (std::size_t k = 0; k < c.transfer_paths.size(); ++k) {
    const fs::path target =
        out.dir / ("transfer_" + fs::path(c.transfer_paths[k]).filename().string());
    const Eigen::MatrixXd& moved = shape.transferred[k];
    offline::transfer_surface(c.transfer_paths[k], target.string(),
                              [&](const Eigen::Vector3d&, long index) -> Eigen::Vector3d {
                                return moved.row(index).transpose();
                              });
    written.push_back(target.string());
  }
  if (scan.image) report["slices"] = write_slices(out, c, shape.surface, scan, written, log);
  // Figs. 16 and 9: the final marker errors' histogram and the convergence plot.
  const fs::path histogram = out.dir / "marker_errors.png",
                 convergence = out.dir / "convergence.png";
  const std::string unit = offline::to_string(c.units);
  const std::string unit_name = unit.empty() ? "template units" : unit;
  std::string error;
  if (!write_error_histogram_png(histogram.string(), shape.marker_errors, unit_name, &error) ||
      !write_convergence_png(convergence.string(), r.registration.summary.iterations, scale,
                             unit_name, &error)) {
    throw std::runtime_error(error);
  }
  written.push_back(histogram.string());
  written.push_back(convergence.string());
  return written;
}

void write_report(const RegisterOutputs& out, const offline::RegisterCaseResult& r,
                  double reading_seconds, double writing_seconds, double total_seconds,
                  nlohmann::json& report, std::vector<std::string>& written) {
  const nlohmann::json phases = {{"reading", reading_seconds + r.seconds.reading},
                                 {"meshing", r.seconds.meshing},
                                 {"embedding", r.seconds.embedding},
                                 {"registration", r.seconds.registration},
                                 {"writing", r.seconds.figures + writing_seconds}};
  const offline::GaussNewtonSummary& summary = r.registration.summary;
  report["outputs"] = written;
  report["totals"] = {{"iterations", summary.iterations.size()},
                      {"equilibrium_solves", summary.equilibrium_solves},
                      {"registration_seconds", summary.seconds},
                      {"seconds", total_seconds},
                      {"phases", phases}};
  write_json_file(out.report().string(), report);
  written.push_back(out.report().string());
}

}  // namespace sinew::tools
