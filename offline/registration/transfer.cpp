#include "offline/registration/transfer.hpp"

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "offline/io/surface_mesh_io.hpp"
#include "offline/registration/registration_case.hpp"

namespace sinew::offline {
namespace fs = std::filesystem;
namespace {

// An OBJ face line with the normal index of each corner removed ("v/vt/vn" -> "v/vt",
// "v//vn" -> "v"): the vn lines are dropped, and a reader would find the indices dangling.
std::string face_without_normals(const std::string& line) {
  std::string out;
  std::istringstream corners(line.substr(1));
  out += 'f';
  std::string corner;
  while (corners >> corner) {
    const std::size_t first = corner.find('/');
    const std::size_t second = first == std::string::npos ? first : corner.find('/', first + 1);
    if (second != std::string::npos) corner.erase(second);
    if (corner.size() == first + 1) corner.erase(first);  // "v/" left of "v//vn"
    out += ' ';
    out += corner;
  }
  return out;
}

}  // namespace

long transfer_surface(const std::string& in_path, const std::string& out_path,
                      const PointTransfer& transfer) {
  std::string extension = fs::path(in_path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  long moved = 0;
  if (extension != ".obj") {
    auto read = offline::io::read_surface_mesh(in_path);
    if (!read.mesh) throw RegistrationInputError(read.error);
    for (Eigen::Index v = 0; v < read.mesh->vertices.rows(); ++v) {
      read.mesh->vertices.row(v) =
          transfer(read.mesh->vertices.row(v).transpose(), moved++).transpose();
    }
    std::string error;
    if (!out_path.empty() && !offline::io::write_surface_mesh(out_path, *read.mesh, &error))
      throw RegistrationInputError(error);
    return moved;
  }
  std::ifstream in(in_path);
  if (!in) throw RegistrationInputError(in_path + ": cannot open file for reading");
  std::ostringstream out;
  out.precision(17);
  std::string line;
  for (long number = 1; std::getline(in, line); ++number) {
    if (line.rfind("vn", 0) == 0) continue;  // normals no longer match the deformed surface
    if (line.size() > 2 && line[0] == 'v' && std::isspace(static_cast<unsigned char>(line[1]))) {
      std::istringstream s(line.substr(2));
      Eigen::Vector3d p;
      if (!(s >> p.x() >> p.y() >> p.z()) || !p.allFinite()) {
        throw RegistrationInputError(in_path + ":" + std::to_string(number) +
                                     ": expected 'v x y z' with finite numbers");
      }
      const Eigen::Vector3d q = transfer(p, moved++);
      out << "v " << q.x() << " " << q.y() << " " << q.z() << "\n";
    } else if (line.size() > 2 && line[0] == 'f' &&
               std::isspace(static_cast<unsigned char>(line[1]))) {
      out << face_without_normals(line) << "\n";
    } else {
      out << line << "\n";
    }
  }
  if (out_path.empty()) return moved;
  const std::string tmp = out_path + ".tmp";
  {
    std::ofstream file(tmp, std::ios::binary);
    file << out.str();
    if (!file) throw RegistrationInputError(out_path + ": cannot write");
  }
  fs::rename(tmp, out_path);
  return moved;
}

}  // namespace sinew::offline
