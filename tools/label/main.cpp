// sinew-label: segmentation label images (NIfTI .nii/.nii.gz, INRIA .inr/.inr.gz) as inputs and
// as a backdrop for sinew-register (seed 003 §4, Figs. 13 and 18).
//
//   sinew-label surface IMAGE --out template.obj [--label N] [--mirror-x C|--mirror-x-centre]
//                             [--smoothing VOXELS] [--cell-size F] [--facet-distance F]
//   sinew-label markers IMAGE --out markers.csv --count N [--label N] [--seed S]
//   sinew-label slices  IMAGE --surface result.obj --out DIR [--mask MASK] [--label N]
//                             [--count K] [--window LO HI] [--zoom Z]
//
// surface: tet-meshes the label's region (its Gaussian-smoothed indicator's 0.5 iso-surface, sub-
// voxel, by CGAL) and writes the boundary surface in the image's world coordinates (millimetres);
// --mirror-x C reflects it across the plane x = C (--mirror-x-centre: the image's centre plane),
// turning a right organ into a left template. markers: N well-spread points on that boundary
// (farthest-point selection over area-weighted samples) as "x,y,z" lines, the ICP markers of a
// case. slices: K axial slices (evenly over the surface's extent) of IMAGE as PNGs, with the
// surface's cross-section in red and, with --mask, the mask's outline in green (Fig. 18), and per
// slice the mean distance from the red curve to the green outline on the terminal. Pictures are
// in radiological orientation (the patient's left on the right, anterior up).
// Exit status 0 ok, 2 bad input (one line on stderr naming the file and what is wrong).

#include <CLI/CLI.hpp>
#include <Eigen/LU>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "offline/io/surface_mesh_io.hpp"
#include "offline/io/volume_image_io.hpp"
#include "offline/meshing/label_image.hpp"
#include "offline/meshing/surface_closest_point.hpp"
#include "tools/io/json_file.hpp"
#include "tools/label/slice_pictures.hpp"

namespace {

namespace fs = std::filesystem;
using sinew::offline::io::VolumeImage;

using sinew::tools::InputError;

VolumeImage read_image(const std::string& path) {
  auto r = sinew::offline::io::read_volume_image(path);
  if (!r.image) throw InputError(r.error);
  return std::move(*r.image);
}

int surface(const std::string& image_path, const std::string& out, int label,
            std::optional<double> mirror, bool mirror_centre, double smoothing, double cell,
            double facet_distance) {
  const VolumeImage image = read_image(image_path);
  sinew::offline::LabelMeshOptions options;
  options.label = label;
  options.smoothing_voxels = smoothing;
  options.mesher.cell_size_fraction = cell;
  options.mesher.facet_distance_fraction = facet_distance;
  if (mirror_centre)
    mirror = image.world(0.5 * (image.size.cast<double>() - Eigen::Vector3d::Ones())).x();
  options.mirror_plane_x = mirror;
  const auto meshed = sinew::offline::mesh_label_region(image, options);
  if (!meshed.summary.ok()) throw InputError(image_path + ": " + meshed.summary.message);
  const auto boundary =
      sinew::offline::BoundarySurface::extract(meshed.mesh.vertices.rows(), meshed.mesh.tets);
  if (!boundary) throw InputError(image_path + ": the region's tet mesh has no valid boundary");
  // The boundary's own vertices, renumbered.
  sinew::offline::io::SurfaceMesh s;
  const auto& used = boundary->vertices();
  std::vector<int> index(static_cast<std::size_t>(meshed.mesh.vertices.rows()), -1);
  s.vertices.resize(static_cast<Eigen::Index>(used.size()), 3);
  for (std::size_t i = 0; i < used.size(); ++i) {
    index[static_cast<std::size_t>(used[i])] = static_cast<int>(i);
    s.vertices.row(static_cast<Eigen::Index>(i)) = meshed.mesh.vertices.row(used[i]);
  }
  s.triangles.resize(boundary->triangles().rows(), 3);
  for (Eigen::Index f = 0; f < s.triangles.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      s.triangles(f, k) = index[static_cast<std::size_t>(boundary->triangles()(f, k))];
  std::string error;
  if (!sinew::offline::io::write_obj(out, s, &error)) throw InputError(error);
  std::printf("%s: %ld tets, boundary %ld vertices / %ld triangles%s -> %s\n", image_path.c_str(),
              static_cast<long>(meshed.mesh.tets.rows()), static_cast<long>(s.vertices.rows()),
              static_cast<long>(s.triangles.rows()),
              mirror ? (", mirrored across x = " + std::to_string(*mirror)).c_str() : "",
              out.c_str());
  return 0;
}

int markers(const std::string& image_path, const std::string& out, int label, int count,
            unsigned seed) {
  const VolumeImage image = read_image(image_path);
  sinew::offline::LabelMeshOptions options;
  options.label = label;
  std::string error;
  const auto points = sinew::offline::sample_label_boundary(image, options, count, seed, &error);
  if (!points) throw InputError(image_path + ": " + error);
  const fs::path tmp = fs::path(out).string() + ".tmp";
  {
    std::ofstream file(tmp);
    file.precision(17);
    file << "x,y,z\n";
    for (const auto& p : *points) file << p.x() << "," << p.y() << "," << p.z() << "\n";
    if (!file) throw InputError(out + ": cannot write");
  }
  fs::rename(tmp, out);
  std::printf("%s: %zu markers on the boundary -> %s\n", image_path.c_str(), points->size(),
              out.c_str());
  return 0;
}

int slices(const std::string& image_path, const std::string& surface_path,
           const std::string& mask_path, const std::string& out_dir, int label, int count,
           double lo, double hi, int zoom) {
  const VolumeImage image = read_image(image_path);
  std::optional<VolumeImage> mask;
  if (!mask_path.empty()) {
    mask = read_image(mask_path);
    if (mask->size != image.size)
      throw InputError(mask_path + ": its grid differs from " + image_path + "'s");
  }
  auto read = sinew::offline::io::read_surface_mesh(surface_path);
  if (!read.mesh) throw InputError(read.error);
  sinew::tools::SlicePictureOptions options;
  options.count = count;
  options.window_low = lo;
  options.window_high = hi;
  options.zoom = zoom;
  options.label = label;
  for (const auto& picture : sinew::tools::write_slice_pictures(image, mask ? &*mask : nullptr,
                                                                *read.mesh, out_dir, options)) {
    if (picture.mean_distance) {
      std::printf(
          "%s: slice k = %d, surface cross-section to mask outline mean %.2f (in-plane, image "
          "units)\n",
          picture.file.c_str(), picture.k, *picture.mean_distance);
    } else {
      std::printf("%s: slice k = %d\n", picture.file.c_str(), picture.k);
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"sinew-label: label images as templates, ICP markers and cross-section pictures"};
  app.require_subcommand(1);
  std::string image, out, surface_path, mask;
  int label = -1, count = 0, zoom = 4;
  unsigned seed = 1;
  double smoothing = 0.8, cell = 0.06, facet_distance = 0.002, mirror_x = 0;
  bool mirror_centre = false;
  std::vector<double> window{-160, 240};
  auto* s =
      app.add_subcommand("surface", "tet-mesh a label's region and write its boundary surface");
  s->add_option("image", image, "label image (.nii, .nii.gz, .inr, .inr.gz)")->required();
  s->add_option("--out", out, "surface file (.obj)")->required();
  s->add_option("--label", label, "label value (default: every voxel > 0.5)");
  auto* mirror_opt = s->add_option("--mirror-x", mirror_x, "mirror across the plane x = C (world)");
  s->add_flag("--mirror-x-centre", mirror_centre,
              "mirror across the image's centre plane x = const");
  s->add_option("--smoothing", smoothing, "Gaussian smoothing of the indicator, voxels");
  s->add_option("--cell-size", cell, "tet size, fraction of the region's diagonal");
  s->add_option("--facet-distance", facet_distance, "surface accuracy, fraction of the diagonal");
  auto* m = app.add_subcommand("markers", "sample well-spread ICP markers on a label's boundary");
  m->add_option("image", image, "label image")->required();
  m->add_option("--out", out, "markers file (.csv)")->required();
  m->add_option("--count", count, "number of markers")->required();
  m->add_option("--label", label, "label value (default: every voxel > 0.5)");
  m->add_option("--seed", seed, "random seed of the candidates");
  auto* c =
      app.add_subcommand("slices", "axial cross-sections of a surface over an image, as PNGs");
  c->add_option("image", image, "background image (CT or mask)")->required();
  c->add_option("--surface", surface_path, "surface (.obj, .off, .stl, .ply)")->required();
  c->add_option("--out", out, "output folder")->required();
  c->add_option("--mask", mask, "mask whose outline is drawn in green");
  c->add_option("--label", label, "label value of the mask (default: every voxel > 0.5)");
  c->add_option("--count", count, "number of slices")->default_val(6);
  c->add_option("--window", window, "grey window LO HI of the background")->expected(2);
  c->add_option("--zoom", zoom, "pixels per voxel");
  CLI11_PARSE(app, argc, argv);
  try {
    if (*s) {
      return surface(image, out, label,
                     mirror_opt->count() ? std::optional<double>(mirror_x) : std::nullopt,
                     mirror_centre, smoothing, cell, facet_distance);
    }
    if (*m) return markers(image, out, label, count, seed);
    if (count <= 0) count = 6;
    return slices(image, surface_path, mask, out, label, count, window[0], window[1], zoom);
  } catch (const std::exception& e) {
    std::cerr << "sinew-label: " << e.what() << "\n";
    return 2;
  }
}
