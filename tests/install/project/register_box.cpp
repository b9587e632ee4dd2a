// Built against the installed Sinew package: registers a box template (written as OBJ) to its
// corners moved by a stretch of 1.2 along x with offline::register_case, the one call
// sinew-register makes, and checks that the registered surface spans the stretched box. Exit 0 on
// success.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "offline/registration/register_case.hpp"

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  const fs::path dir = argc > 1 ? fs::path(argv[1]) : fs::temp_directory_path() / "sinew_box";
  fs::create_directories(dir);
  const fs::path obj = dir / "box.obj";
  {
    // A box 40 x 20 x 20 mm, corners at 0 and (40, 20, 20).
    std::ofstream out(obj);
    for (int k = 0; k < 8; ++k) {
      out << "v " << 40 * (k & 1) << ' ' << 20 * ((k >> 1) & 1) << ' ' << 20 * ((k >> 2) & 1)
          << '\n';
    }
    const int faces[12][3] = {{1, 3, 4}, {1, 4, 2}, {5, 6, 8}, {5, 8, 7}, {1, 2, 6}, {1, 6, 5},
                              {3, 7, 8}, {3, 8, 4}, {1, 5, 7}, {1, 7, 3}, {2, 4, 8}, {2, 8, 6}};
    for (const auto& f : faces) out << "f " << f[0] << ' ' << f[1] << ' ' << f[2] << '\n';
  }
  sinew::offline::RegistrationCase c;
  c.case_path = (dir / "box.json").string();
  c.template_path = obj.string();
  c.units = sinew::offline::LengthUnit::kMillimetre;
  c.attachments.template_points.resize(8, 3);
  c.attachments.target_points.resize(8, 3);
  for (int k = 0; k < 8; ++k) {
    const Eigen::RowVector3d p(40 * (k & 1), 20 * ((k >> 1) & 1), 20 * ((k >> 2) & 1));
    c.attachments.template_points.row(k) = p;
    c.attachments.target_points.row(k) = Eigen::RowVector3d(1.2 * p.x(), p.y(), p.z());
  }
  c.attachments.source = c.case_path;
  c.attachments.template_source = c.case_path;
  c.stop.max_iterations_per_stage = 10;
  c.mesh.cell_size_fraction = 0.15;  // a coarse mesh: a box needs no more, and the test is quick
  c.mesh.facet_distance_fraction = 0.01;
  try {
    const sinew::offline::RegisterCaseResult r = sinew::offline::register_case(c, {});
    if (!r.shape) {
      std::fprintf(stderr, "register_box: no usable registration\n");
      return 1;
    }
    const Eigen::MatrixXd& v = r.shape->surface.vertices;
    const double length = v.col(0).maxCoeff() - v.col(0).minCoeff();
    const double width = v.col(1).maxCoeff() - v.col(1).minCoeff();
    std::printf("register_box: %lld tets, the box's length 40 -> %.3f mm (target 48), width %.3f\n",
                static_cast<long long>(r.inputs.tets), length, width);
    return std::abs(length - 48.0) < 1.0 && std::abs(width - 20.0) < 1.0 ? 0 : 1;
  } catch (const sinew::offline::RegistrationInputError& e) {
    std::fprintf(stderr, "register_box: %s\n", e.what());
    return 1;
  }
}
