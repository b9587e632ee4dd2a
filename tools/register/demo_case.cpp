#include "tools/register/demo_case.hpp"

#include <fmt/core.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <tuple>
#include <vector>

#include "tools/io/json_file.hpp"

namespace sinew::tools {
namespace {

namespace fs = std::filesystem;
using offline::io::SurfaceMesh;

SurfaceMesh to_mesh(const std::vector<Eigen::Vector3d>& vertices,
                    const std::vector<Eigen::Vector3i>& triangles) {
  SurfaceMesh mesh;
  mesh.vertices.resize(static_cast<Eigen::Index>(vertices.size()), 3);
  for (std::size_t i = 0; i < vertices.size(); ++i)
    mesh.vertices.row(static_cast<Eigen::Index>(i)) = vertices[i].transpose();
  mesh.triangles.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (std::size_t i = 0; i < triangles.size(); ++i)
    mesh.triangles.row(static_cast<Eigen::Index>(i)) = triangles[i].transpose();
  return mesh;
}

// Reverses every triangle when the surface encloses a negative volume (normals inward).
void orient_outward(SurfaceMesh& mesh) {
  if (offline::io::check_surface(mesh).signed_volume >= 0) return;
  mesh.triangles.col(1).swap(mesh.triangles.col(2));
}

// Uniform in [0, 1) from a 32-bit Mersenne twister, the same on every platform
// (std::uniform_real_distribution is implementation-defined).
class Uniform {
 public:
  explicit Uniform(unsigned seed) : rng_(seed) {}
  double operator()() { return (static_cast<double>(rng_()) + 0.5) / 4294967296.0; }

 private:
  std::mt19937 rng_;
};

nlohmann::json xyz(const Eigen::Vector3d& p) {
  return {p.x(), p.y(), p.z()};
}

void write_text_file(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  out.close();
  if (!out) throw InputError(path.string() + ": cannot write");
}

}  // namespace

SurfaceMesh box_surface(const Eigen::Vector3d& size, const Eigen::Vector3i& n) {
  std::map<std::tuple<int, int, int>, int> index;
  std::vector<Eigen::Vector3d> vertices;
  auto vertex = [&](int i, int j, int k) {
    const auto key = std::make_tuple(i, j, k);
    auto it = index.find(key);
    if (it != index.end()) return it->second;
    vertices.push_back(
        Eigen::Vector3d(size.x() * i / n.x(), size.y() * j / n.y(), size.z() * k / n.z()));
    return index[key] = static_cast<int>(vertices.size()) - 1;
  };
  std::vector<Eigen::Vector3i> triangles;
  const Eigen::Vector3d centre = size / 2;
  auto add = [&](int a, int b, int c) {
    const Eigen::Vector3d pa = vertices[a], pb = vertices[b], pc = vertices[c];
    const Eigen::Vector3d normal = (pb - pa).cross(pc - pa);
    if (normal.dot((pa + pb + pc) / 3 - centre) > 0) {
      triangles.emplace_back(a, b, c);
    } else {
      triangles.emplace_back(a, c, b);
    }
  };
  // Each face: fix one lattice axis at 0 or n, grid the other two.
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (int side : {0, n[axis]}) {
      for (int a = 0; a < n[u]; ++a) {
        for (int b = 0; b < n[v]; ++b) {
          auto at = [&](int da, int db) {
            Eigen::Vector3i ijk;
            ijk[axis] = side;
            ijk[u] = a + da;
            ijk[v] = b + db;
            return vertex(ijk[0], ijk[1], ijk[2]);
          };
          const int p00 = at(0, 0), p10 = at(1, 0), p11 = at(1, 1), p01 = at(0, 1);
          add(p00, p10, p11);
          add(p00, p11, p01);
        }
      }
    }
  }
  return to_mesh(vertices, triangles);
}

SurfaceMesh capsule_surface(const CapsuleShape& s) {
  // Profile rings (x, scale of the cross-section), pole to pole, poles excluded.
  std::vector<std::pair<double, double>> rings;
  const double pi = std::acos(-1.0);
  for (int i = 1; i <= s.cap_rings; ++i) {
    const double a = 0.5 * pi * i / s.cap_rings;  // from the pole
    rings.emplace_back(s.cap_length * (1 - std::cos(a)), std::sin(a));
  }
  const double body = s.length - 2 * s.cap_length;
  for (int i = 1; i < s.body_sections; ++i)
    rings.emplace_back(s.cap_length + body * i / s.body_sections, 1.0);
  for (int i = s.cap_rings; i >= 1; --i) {
    const double a = 0.5 * pi * i / s.cap_rings;
    rings.emplace_back(s.length - s.cap_length * (1 - std::cos(a)), std::sin(a));
  }
  std::vector<Eigen::Vector3d> vertices{Eigen::Vector3d::Zero()};
  for (const auto& [x, scale] : rings) {
    for (int k = 0; k < s.segments; ++k) {
      const double phi = 2 * pi * k / s.segments;
      vertices.emplace_back(x, scale * s.radius_y * std::cos(phi),
                            scale * s.radius_z * std::sin(phi));
    }
  }
  vertices.emplace_back(s.length, 0.0, 0.0);
  const int n = s.segments, last_pole = static_cast<int>(vertices.size()) - 1;
  const int num_rings = static_cast<int>(rings.size());
  auto at = [&](int ring, int k) { return 1 + ring * n + (k % n); };
  std::vector<Eigen::Vector3i> triangles;
  for (int k = 0; k < n; ++k) {
    triangles.emplace_back(0, at(0, k + 1), at(0, k));
    triangles.emplace_back(last_pole, at(num_rings - 1, k), at(num_rings - 1, k + 1));
  }
  for (int r = 0; r + 1 < num_rings; ++r) {
    for (int k = 0; k < n; ++k) {
      triangles.emplace_back(at(r, k), at(r, k + 1), at(r + 1, k + 1));
      triangles.emplace_back(at(r, k), at(r + 1, k + 1), at(r + 1, k));
    }
  }
  SurfaceMesh mesh = to_mesh(vertices, triangles);
  orient_outward(mesh);
  return mesh;
}

Eigen::Vector3d AxialStretchBend::operator()(const Eigen::Vector3d& p) const {
  if (p.x() <= attached_until) return p;
  const double t = (p.x() - attached_until) / free_length;
  // Composite Simpson on the axis's tangent (cos θ, sin θ)·σ'(τ) (plain doubles: GCC 12 warns
  // falsely on small Eigen temporaries here).
  constexpr int kIntervals = 64;  // even
  const double h = t / kIntervals;
  double axis_x = 0.0, axis_y = 0.0;
  for (int i = 0; i <= kIntervals; ++i) {
    const double tau = i * h;
    const double theta = bend_radians * tau * tau;
    const double dsigma = free_length * (1 + 2 * stretch * tau);
    const double w = (i == 0 || i == kIntervals) ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0);
    axis_x += w * std::cos(theta) * dsigma;
    axis_y += w * std::sin(theta) * dsigma;
  }
  axis_x = attached_until + axis_x * h / 3;
  axis_y *= h / 3;
  const double theta = bend_radians * t * t;
  return Eigen::Vector3d(axis_x - p.y() * std::sin(theta), axis_y + p.y() * std::cos(theta), p.z());
}

DemoCase make_demo_case(const DemoCaseOptions& options) {
  DemoCase demo;
  demo.options = options;
  const CapsuleShape& shape = options.shape;
  demo.template_surface = capsule_surface(shape);
  demo.deformation.attached_until = shape.cap_length;
  demo.deformation.free_length = shape.length - shape.cap_length;
  demo.deformation.stretch = options.stretch;
  demo.deformation.bend_radians = options.bend_radians;

  const SurfaceMesh& surface = demo.template_surface;
  demo.truth_surface.triangles = surface.triangles;
  demo.truth_surface.vertices.resize(surface.vertices.rows(), 3);
  std::vector<Eigen::Index> attached;
  for (Eigen::Index v = 0; v < surface.vertices.rows(); ++v) {
    const Eigen::Vector3d p = surface.vertices.row(v).transpose();
    const Eigen::Vector3d q = demo.deformation(p);
    demo.truth_surface.vertices.row(v) = q.transpose();
    demo.max_displacement = std::max(demo.max_displacement, (q - p).norm());
    // The attached end: the cap's vertices up to 40% of its length from the pole.
    if (p.x() <= 0.4 * shape.cap_length) attached.push_back(v);
  }
  demo.attachment_points.resize(static_cast<Eigen::Index>(attached.size()), 3);
  for (std::size_t i = 0; i < attached.size(); ++i)
    demo.attachment_points.row(static_cast<Eigen::Index>(i)) = surface.vertices.row(attached[i]);

  // Markers: points drawn uniformly by area on the template's triangles beyond the attached cap
  // (a scan sees the free part), mapped by φ onto the smooth deformed surface.
  std::vector<double> cumulative_area;
  std::vector<Eigen::Index> faces;
  double total = 0.0;
  for (Eigen::Index f = 0; f < surface.triangles.rows(); ++f) {
    const Eigen::Vector3d a = surface.vertices.row(surface.triangles(f, 0)).transpose();
    const Eigen::Vector3d b = surface.vertices.row(surface.triangles(f, 1)).transpose();
    const Eigen::Vector3d c = surface.vertices.row(surface.triangles(f, 2)).transpose();
    if (std::min({a.x(), b.x(), c.x()}) < shape.cap_length) continue;
    total += 0.5 * (b - a).cross(c - a).norm();
    cumulative_area.push_back(total);
    faces.push_back(f);
  }
  Uniform uniform(options.seed);
  demo.markers.resize(options.markers, 3);
  for (int m = 0; m < options.markers; ++m) {
    const double pick = uniform() * total;
    const std::size_t i = static_cast<std::size_t>(
        std::lower_bound(cumulative_area.begin(), cumulative_area.end(), pick) -
        cumulative_area.begin());
    const Eigen::Index f = faces[std::min(i, faces.size() - 1)];
    double u = uniform(), v = uniform();
    if (u + v > 1) {
      u = 1 - u;
      v = 1 - v;
    }
    const Eigen::Vector3d p = (1 - u - v) * surface.vertices.row(surface.triangles(f, 0)) +
                              u * surface.vertices.row(surface.triangles(f, 1)) +
                              v * surface.vertices.row(surface.triangles(f, 2));
    demo.markers.row(m) = demo.deformation(p).transpose();
  }
  return demo;
}

void write_demo_case(const DemoCase& demo, const std::string& dir_name) {
  const fs::path dir(dir_name);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw InputError(dir.string() + ": cannot create folder (" + ec.message() + ")");
  std::string error;
  if (!offline::io::write_obj((dir / "template.obj").string(), demo.template_surface, &error) ||
      !offline::io::write_obj((dir / "truth_surface.obj").string(), demo.truth_surface, &error))
    throw InputError(error);

  std::string csv = "x,y,z\n";
  char line[128];
  for (Eigen::Index m = 0; m < demo.markers.rows(); ++m) {
    std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g\n", demo.markers(m, 0), demo.markers(m, 1),
                  demo.markers(m, 2));
    csv += line;
  }
  write_text_file(dir / "markers.csv", csv);

  nlohmann::json attachments = nlohmann::json::array();
  for (Eigen::Index a = 0; a < demo.attachment_points.rows(); ++a) {
    const Eigen::Vector3d p = demo.attachment_points.row(a).transpose();
    attachments.push_back({{"template", xyz(p)}, {"target", xyz(p)}});
  }
  write_json_file((dir / "attachments.json").string(), attachments);

  const nlohmann::json case_json = {
      {"template", "template.obj"},
      {"units", "mm"},
      {"mesh",
       {{"cell_size_fraction", demo.options.cell_size_fraction},
        {"facet_distance_fraction", demo.options.facet_distance_fraction}}},
      {"attachments", "attachments.json"},
      {"icp_markers", "markers.csv"},
      {"stop", {{"max_iterations", demo.options.max_iterations}}}};
  write_json_file((dir / "case.json").string(), case_json);
}

std::string demo_case_summary(const DemoCase& demo, const std::string& dir) {
  return fmt::format(
      "wrote {}/case.json: a {:g} x {:g} x {:g} mm capsule ({} vertices) attached at its x = 0 end "
      "by {} points; {} ICP markers on its known deformation (free part {:g}x longer, bent {:.0f} "
      "degrees; vertices move up to {:.1f} mm), {}/truth_surface.obj",
      dir, demo.options.shape.length, 2 * demo.options.shape.radius_y,
      2 * demo.options.shape.radius_z, demo.template_surface.vertices.rows(),
      demo.attachment_points.rows(), demo.markers.rows(), 1 + demo.options.stretch,
      demo.options.bend_radians * 180 / std::acos(-1.0), demo.max_displacement, dir);
}

}  // namespace sinew::tools
