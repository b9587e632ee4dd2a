#include "tools/register/checkpoint_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "tools/io/json_file.hpp"

namespace sinew::tools {
namespace {

namespace fs = std::filesystem;
using offline::GaussNewtonIteration;
using offline::GaussNewtonTermination;
using offline::RegistrationStage;

constexpr const char* kFormat = "sinew-register checkpoint";
constexpr int kVersion = 1;

constexpr RegistrationStage kStages[] = {
    RegistrationStage::kInitialFit, RegistrationStage::kAttachments, RegistrationStage::kLandmarks,
    RegistrationStage::kIcpMarkers};
constexpr GaussNewtonTermination kTerminations[] = {GaussNewtonTermination::kMaxIterations,
                                                    GaussNewtonTermination::kMarkerTolerance,
                                                    GaussNewtonTermination::kSmallStep,
                                                    GaussNewtonTermination::kSmallDecrease,
                                                    GaussNewtonTermination::kLineSearchFailed,
                                                    GaussNewtonTermination::kEquilibriumFailed,
                                                    GaussNewtonTermination::kLinearSolveFailed,
                                                    GaussNewtonTermination::kInvalidInput,
                                                    GaussNewtonTermination::kStalled};

// A checkpoint's values, read through JsonCursor (every failure names the file, the line and
// column and the field). Doubles are hex-float strings, exact to the bit.
double hex_real(const JsonCursor& c) {
  if (!c.value().is_string()) c.fail("is not a hex-float string");
  const std::string text = c.value().get<std::string>();
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size()) c.fail("= '" + text + "' is bad");
  return value;
}

Eigen::VectorXd hex_vector(const JsonCursor& c) {
  Eigen::VectorXd v(static_cast<Eigen::Index>(c.array_size()));
  for (Eigen::Index i = 0; i < v.size(); ++i) v[i] = hex_real(c.at(static_cast<std::size_t>(i)));
  return v;
}

RegistrationStage stage(const JsonCursor& c) {
  const std::string name = c.string();
  for (RegistrationStage s : kStages)
    if (name == offline::to_string(s)) return s;
  c.fail("= '" + name + "' is not a stage");
}

GaussNewtonTermination termination(const JsonCursor& c) {
  const std::string name = c.string();
  for (GaussNewtonTermination t : kTerminations)
    if (name == offline::to_string(t)) return t;
  c.fail("= '" + name + "' is not a termination");
}

nlohmann::json vector_json(const Eigen::VectorXd& v) {
  nlohmann::json out = nlohmann::json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) out.push_back(hex_double(v[i]));
  return out;
}

nlohmann::json iteration_json(const GaussNewtonIteration& it) {
  return {{"stage", offline::to_string(it.stage)},
          {"iteration", it.iteration},
          {"objective", hex_double(it.objective)},
          {"objective_before", hex_double(it.objective_before)},
          {"predicted_decrease", hex_double(it.predicted_decrease)},
          {"step", hex_double(it.step)},
          {"marker_error_mean", hex_double(it.marker_error_mean)},
          {"marker_error_max", hex_double(it.marker_error_max)},
          {"equilibrium_solves", it.equilibrium_solves},
          {"clamped_tets", it.clamped_tets},
          {"projected_search", it.projected_search},
          {"inverted_equilibrium", it.inverted_equilibrium},
          {"held_tets", it.held_tets},
          {"held_by_elimination", it.held_by_elimination},
          {"damping", hex_double(it.damping)},
          {"jacobian_seconds", hex_double(it.jacobian_seconds)},
          {"woodbury_seconds", hex_double(it.woodbury_seconds)},
          {"line_search_seconds", hex_double(it.line_search_seconds)},
          {"seconds", hex_double(it.seconds)}};
}

GaussNewtonIteration read_iteration(const JsonCursor& j) {
  GaussNewtonIteration it;
  const auto real = [&](const char* key) { return hex_real(j.at(key)); };
  it.stage = stage(j.at("stage"));
  it.iteration = static_cast<int>(j.at("iteration").integer());
  it.objective = real("objective");
  it.objective_before = real("objective_before");
  it.predicted_decrease = real("predicted_decrease");
  it.step = real("step");
  it.marker_error_mean = real("marker_error_mean");
  it.marker_error_max = real("marker_error_max");
  it.equilibrium_solves = static_cast<int>(j.at("equilibrium_solves").integer());
  it.clamped_tets = static_cast<int>(j.at("clamped_tets").integer());
  // Absent in checkpoints written before the projected-search fallback existed.
  if (j.has("projected_search")) it.projected_search = j.at("projected_search").boolean();
  // Absent in checkpoints written before the inverted-equilibrium fallback existed.
  if (j.has("inverted_equilibrium"))
    it.inverted_equilibrium = j.at("inverted_equilibrium").boolean();
  // Absent in checkpoints written before the held-tet counts were reported.
  if (j.has("held_tets")) it.held_tets = static_cast<int>(j.at("held_tets").integer());
  if (j.has("held_by_elimination")) it.held_by_elimination = j.at("held_by_elimination").boolean();
  // Absent in checkpoints written before the damped steps existed (undamped).
  if (j.has("damping")) it.damping = real("damping");
  it.jacobian_seconds = real("jacobian_seconds");
  it.woodbury_seconds = real("woodbury_seconds");
  it.line_search_seconds = real("line_search_seconds");
  it.seconds = real("seconds");
  return it;
}

std::string describe(const nlohmann::json& j) {
  return j.is_string() ? j.get<std::string>() : j.dump();
}

}  // namespace

std::string hex_double(double value) {
  char buffer[64];
  const int n = std::snprintf(buffer, sizeof buffer, "%a", value);
  return std::string(buffer, static_cast<std::size_t>(n));
}

std::uint64_t fnv1a(const void* data, std::size_t bytes, std::uint64_t hash) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < bytes; ++i) {
    hash ^= p[i];
    hash *= 1099511628211ULL;
  }
  return hash;
}

fs::path checkpoint_path(const fs::path& out_dir) {
  return out_dir / "checkpoint.sinew";
}

void write_checkpoint(const fs::path& path, const RegisterCheckpoint& checkpoint) {
  nlohmann::json j;
  j["format"] = kFormat;
  j["version"] = kVersion;
  j["case"] = checkpoint.case_path;
  j["case_file"] = checkpoint.case_file;
  j["truth"] = checkpoint.truth_path;
  j["truth_file"] = checkpoint.truth_file;
  j["max_iterations"] = checkpoint.max_iterations ? nlohmann::json(*checkpoint.max_iterations)
                                                  : nlohmann::json(nullptr);
  j["resumes"] = checkpoint.resumes;
  j["identification"] = checkpoint.identification;
  if (checkpoint.state) {
    const offline::GaussNewtonCheckpoint& s = *checkpoint.state;
    nlohmann::json state;
    state["free_object"] = s.free_object;
    state["next_stage"] =
        s.next_stage ? nlohmann::json(offline::to_string(*s.next_stage)) : nlohmann::json(nullptr);
    state["next_iteration"] = s.next_iteration;
    state["termination"] = offline::to_string(s.termination);
    state["initial_objective"] = hex_double(s.initial_objective);
    state["equilibrium_solves"] = s.equilibrium_solves;
    state["seconds"] = hex_double(s.seconds);
    nlohmann::json iterations = nlohmann::json::array();
    for (const GaussNewtonIteration& it : s.iterations) iterations.push_back(iteration_json(it));
    state["iterations"] = iterations;
    state["s"] = vector_json(s.s);
    state["x"] = vector_json(s.x);
    j["state"] = state;
  } else {
    j["state"] = nullptr;
  }
  const std::string text = j.dump() + "\n";

  const std::string tmp = path.string() + ".tmp" + std::to_string(static_cast<long>(::getpid()));
  const auto failed = [&](const std::string& what) {
    const std::string reason = std::strerror(errno);
    ::unlink(tmp.c_str());
    throw std::runtime_error(path.string() + ": " + what + " (" + reason + ")");
  };
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) failed("cannot open for writing");
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      ::close(fd);
      failed("write error");
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    ::close(fd);
    failed("fsync failed");
  }
  if (::close(fd) != 0) failed("close failed");
  if (std::rename(tmp.c_str(), path.c_str()) != 0) failed("cannot move into place");
  // The rename itself is durable once the folder is synced.
  const fs::path folder = path.has_parent_path() ? path.parent_path() : fs::path(".");
  const int dir = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir >= 0) {
    ::fsync(dir);
    ::close(dir);
  }
}

RegisterCheckpoint read_checkpoint(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    throw InputError(path.string() +
                     ": no checkpoint to resume from (the run finished, see report.json, or "
                     "this is not a sinew-register output folder)");
  }
  const std::string file = path.string();
  return parse_json_file(file, [&](const nlohmann::json& j) {
    try {
      return parse_checkpoint(j, file);
    } catch (const JsonValueError& e) {
      throw e.appended(" (not a sinew-register checkpoint, or a damaged one)");
    }
  });
}

RegisterCheckpoint parse_checkpoint(const nlohmann::json& j, const std::string& file) {
  const JsonCursor root(j, file);
  if (!j.is_object() || !j.contains("format") || j["format"] != kFormat) {
    (j.is_object() && j.contains("format") ? root.at("format") : root)
        .fail("is not '" + std::string(kFormat) + "'");
  }
  if (root.at("version").integer() != kVersion) {
    root.at("version").fail("is not " + std::to_string(kVersion));
  }
  RegisterCheckpoint c;
  c.case_path = root.at("case").string();
  c.case_file = root.at("case_file").string();
  c.truth_path = root.at("truth").string();
  c.truth_file = root.at("truth_file").string();
  const JsonCursor max_iterations = root.at("max_iterations");
  if (!max_iterations.value().is_null()) {
    c.max_iterations = static_cast<int>(max_iterations.integer());
  }
  c.resumes = static_cast<int>(root.at("resumes").integer());
  const JsonCursor identification = root.at("identification");
  if (!identification.value().is_object()) identification.fail("is not an object");
  c.identification = identification.value();
  const JsonCursor state = root.at("state");
  if (state.value().is_null()) return c;
  offline::GaussNewtonCheckpoint s;
  s.free_object = state.at("free_object").boolean();
  const JsonCursor next_stage = state.at("next_stage");
  if (!next_stage.value().is_null()) s.next_stage = stage(next_stage);
  s.next_iteration = static_cast<int>(state.at("next_iteration").integer());
  s.termination = termination(state.at("termination"));
  s.initial_objective = hex_real(state.at("initial_objective"));
  s.equilibrium_solves = static_cast<int>(state.at("equilibrium_solves").integer());
  s.seconds = hex_real(state.at("seconds"));
  const JsonCursor iterations = state.at("iterations");
  for (std::size_t i = 0; i < iterations.array_size(); ++i) {
    s.iterations.push_back(read_iteration(iterations.at(i)));
  }
  s.s = hex_vector(state.at("s"));
  s.x = hex_vector(state.at("x"));
  c.state = std::move(s);
  return c;
}

std::optional<std::string> identification_mismatch(const nlohmann::json& saved,
                                                   const nlohmann::json& now) {
  // The most telling difference first: a changed template shows in the mesh before it shows in
  // the markers' embedding.
  for (const char* key : {"mode", "tet_vertices", "tets", "mesh_hash", "attachments", "landmarks",
                          "icp_markers", "markers_hash", "surface_hash"}) {
    if (now.contains(key) && saved.contains(key) && saved[key] != now[key]) {
      return std::string(key) + ": " + describe(saved[key]) + " in the checkpoint, " +
             describe(now[key]) + " now";
    }
  }
  for (const auto& [key, value] : now.items()) {
    if (!saved.contains(key))
      return key + ": missing in the checkpoint, " + describe(value) + " now";
    if (saved[key] != value) {
      if (value.is_object() && saved[key].is_object()) {
        if (auto inner = identification_mismatch(saved[key], value)) return key + "." + *inner;
      }
      return key + ": " + describe(saved[key]) + " in the checkpoint, " + describe(value) + " now";
    }
  }
  for (const auto& [key, value] : saved.items()) {
    if (!now.contains(key)) return key + ": " + describe(value) + " in the checkpoint, none now";
  }
  return std::nullopt;
}

namespace {

// 64-bit hash of a matrix's coefficients.
template <typename Matrix>
std::uint64_t hash_matrix(const Matrix& m, std::uint64_t hash = kFnvOffset) {
  return fnv1a(m.data(), sizeof(typename Matrix::Scalar) * static_cast<std::size_t>(m.size()),
               hash);
}
std::uint64_t hash_points(const std::vector<offline::EmbeddedPoint>& points, std::uint64_t hash) {
  for (const offline::EmbeddedPoint& p : points) {
    const long long tet = static_cast<long long>(p.tet);
    hash = fnv1a(&tet, sizeof tet, hash);
    hash = hash_matrix(p.weights, hash);
  }
  return hash;
}
std::uint64_t hash_constraints(const std::vector<offline::PointConstraint>& list,
                               std::uint64_t hash) {
  for (const offline::PointConstraint& c : list) {
    hash = hash_points({c.point}, hash);
    hash = hash_matrix(c.target, hash);
    hash = fnv1a(&c.weight, sizeof c.weight, hash);
  }
  return hash;
}
std::string hex(std::uint64_t value) {
  char text[32];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(value));
  return text;
}

}  // namespace

nlohmann::json run_identification(const offline::PreparedCase& p,
                                  offline::SparseCholeskyMethod cholesky) {
  const offline::GaussNewtonOptions& options = p.options;
  const offline::RegistrationConstraints& constraints = p.constraints;
  nlohmann::json identification;
  identification["mode"] = p.free_object ? "free" : "attached";
  // A free object's checkpointed state is in the template's frame since issue 18 (register_free
  // moves the scan onto the template); an older checkpoint's is in the scan's.
  if (p.free_object) identification["free_object_frame"] = "template";
  identification["tet_vertices"] = p.rest.rows();
  identification["tets"] = p.tets.rows();
  identification["mesh_hash"] = hex(hash_matrix(p.tets, hash_matrix(p.rest)));
  identification["attachments"] = constraints.attachments.size();
  identification["landmarks"] = constraints.landmarks.size();
  identification["icp_markers"] = constraints.icp_markers.size();
  std::uint64_t h = hash_constraints(constraints.attachments, kFnvOffset);
  h = hash_constraints(constraints.landmarks, h);
  for (const Eigen::Vector3d& z : constraints.icp_markers) h = hash_matrix(z, h);
  identification["markers_hash"] = hex(h);
  identification["surface_hash"] =
      hex(hash_matrix(p.surface_triangles, hash_points(p.surface_points, kFnvOffset)));
  identification["options"] = {{"alpha", hex_double(options.alpha)},
                               {"beta", hex_double(options.beta)},
                               {"attachment_stiffness", hex_double(p.attachment_stiffness)},
                               {"max_iterations_per_stage", options.max_iterations_per_stage},
                               {"max_marker_error", hex_double(options.max_marker_error)},
                               {"min_step", hex_double(options.min_step)},
                               {"icp_stage_landmarks", options.icp_stage_landmarks},
                               {"landmark_stage", options.landmark_stage},
                               {"damped_step_trials", options.damped_step_trials},
                               {"predictor_warm_start", options.predictor_warm_start},
                               {"hold_clamped_tets", options.hold_clamped_tets},
                               {"icp_no_progress_iterations", options.icp_no_progress_iterations},
                               {"eigenvalue_floor", hex_double(options.eigenvalue_floor)},
                               {"cholesky", offline::to_string(cholesky)}};
  for (const double f : options.icp_weight_ramp)
    identification["options"]["icp_weight_ramp"].push_back(hex_double(f));
  // Issue 51's options only when set, so that checkpoints written without them stay resumable.
  if (options.constant_strain_step_limit > 0.0)
    identification["options"]["constant_strain_step_limit"] =
        hex_double(options.constant_strain_step_limit);
  if (options.inverted_equilibrium_fallback)
    identification["options"]["inverted_equilibrium_fallback"] = true;
  if (options.constant_strain_step_limit > 0.0 || options.inverted_equilibrium_fallback)
    identification["options"]["rescue_min_damping"] = hex_double(options.rescue_min_damping);
  return identification;
}

void check_resumable(const RegisterCheckpoint& saved, const nlohmann::json& identification,
                     bool free_object, const std::filesystem::path& checkpoint,
                     const std::string& case_path) {
  if (const auto mismatch = identification_mismatch(saved.identification, identification)) {
    throw InputError(checkpoint.string() + ": does not match " + case_path + " as it is now (" +
                     *mismatch +
                     "): the case, its template or its markers changed since the run "
                     "started; start it again with --case");
  }
  if (saved.state && saved.state->free_object != free_object) {
    throw InputError(checkpoint.string() + ": its state is of a " +
                     (free_object ? "attached" : "free") + " object, the case's is not");
  }
}

}  // namespace sinew::tools
