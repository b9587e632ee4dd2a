#include "offline/io/volume_image_io.hpp"

#include <zlib.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <sstream>

#include "offline/io/io_common.hpp"

namespace sinew::offline::io {
namespace {

using detail::fail;

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// The whole (decompressed) file: zlib reads plain files as they are.
std::vector<unsigned char> read_all(const std::string& path) {
  gzFile file = gzopen(path.c_str(), "rb");
  if (file == nullptr) fail(path + ": cannot open file for reading");
  std::vector<unsigned char> bytes;
  unsigned char buffer[1 << 16];
  int n = 0;
  while ((n = gzread(file, buffer, sizeof(buffer))) > 0)
    bytes.insert(bytes.end(), buffer, buffer + n);
  const bool error = n < 0;
  gzclose(file);
  if (error) fail(path + ": corrupt gzip data");
  return bytes;
}

template <class T>
T read_at(const std::vector<unsigned char>& bytes, std::size_t offset) {
  T value;
  std::memcpy(&value, bytes.data() + offset, sizeof(T));
  return value;
}

// Raw voxel values of `count` voxels of one type starting at offset, as float.
void convert(const std::string& path, const std::vector<unsigned char>& bytes, std::size_t offset,
             std::size_t count, const std::string& type, bool swap, std::vector<float>& out) {
  static const std::map<std::string, std::size_t> sizes{
      {"u8", 1}, {"i8", 1}, {"u16", 2}, {"i16", 2}, {"u32", 4}, {"i32", 4}, {"f32", 4}, {"f64", 8}};
  const std::size_t size = sizes.at(type);
  if (bytes.size() < offset + count * size) {
    std::ostringstream s;
    s << path << ": truncated voxel data: " << count << " voxels of " << size << " bytes need "
      << offset + count * size << " bytes, the file has " << bytes.size();
    fail(s.str());
  }
  out.resize(count);
  unsigned char word[8];
  for (std::size_t v = 0; v < count; ++v) {
    const unsigned char* p = bytes.data() + offset + v * size;
    for (std::size_t b = 0; b < size; ++b) word[b] = swap ? p[size - 1 - b] : p[b];
    float value = 0.0f;
    if (type == "u8") value = static_cast<float>(word[0]);
    if (type == "i8") value = static_cast<float>(static_cast<std::int8_t>(word[0]));
    if (type == "u16") {
      std::uint16_t x;
      std::memcpy(&x, word, 2);
      value = static_cast<float>(x);
    }
    if (type == "i16") {
      std::int16_t x;
      std::memcpy(&x, word, 2);
      value = static_cast<float>(x);
    }
    if (type == "u32") {
      std::uint32_t x;
      std::memcpy(&x, word, 4);
      value = static_cast<float>(x);
    }
    if (type == "i32") {
      std::int32_t x;
      std::memcpy(&x, word, 4);
      value = static_cast<float>(x);
    }
    if (type == "f32") std::memcpy(&value, word, 4);
    if (type == "f64") {
      double x;
      std::memcpy(&x, word, 8);
      value = static_cast<float>(x);
    }
    out[v] = value;
  }
}

VolumeImage read_nifti(const std::string& path) {
  const std::vector<unsigned char> bytes = read_all(path);
  if (bytes.size() < 348) fail(path + ": not a NIfTI-1 file (shorter than its 348-byte header)");
  const int header_size = read_at<std::int32_t>(bytes, 0);
  if (header_size != 348) {
    fail(path + ": not a little-endian NIfTI-1 file (sizeof_hdr = " + std::to_string(header_size) +
         ", expected 348; NIfTI-2 and big-endian files are not supported)");
  }
  const std::string magic(reinterpret_cast<const char*>(bytes.data() + 344), 3);
  if (magic != "n+1") fail(path + ": NIfTI magic is '" + magic + "', expected 'n+1' (single file)");
  std::int16_t dim[8];
  for (int d = 0; d < 8; ++d)
    dim[d] = read_at<std::int16_t>(bytes, 40 + 2 * static_cast<std::size_t>(d));
  if (dim[0] < 3 || dim[0] > 7)
    fail(path + ": dim[0] = " + std::to_string(dim[0]) + ", expected 3");
  for (int d = 4; d <= dim[0]; ++d) {
    if (dim[d] > 1)
      fail(path + ": a " + std::to_string(dim[0]) + "D image; only 3D volumes are read");
  }
  VolumeImage image;
  image.size = Eigen::Vector3i(dim[1], dim[2], dim[3]);
  if ((image.size.array() <= 0).any()) fail(path + ": an image size is not positive");
  const std::int16_t datatype = read_at<std::int16_t>(bytes, 70);
  static const std::map<int, std::string> types{{2, "u8"},    {4, "i16"},  {8, "i32"},
                                                {16, "f32"},  {64, "f64"}, {256, "i8"},
                                                {512, "u16"}, {768, "u32"}};
  const auto type = types.find(datatype);
  if (type == types.end()) fail(path + ": unsupported NIfTI datatype " + std::to_string(datatype));
  float pixdim[8];
  for (int d = 0; d < 8; ++d)
    pixdim[d] = read_at<float>(bytes, 76 + 4 * static_cast<std::size_t>(d));
  const float vox_offset = read_at<float>(bytes, 108);
  const float slope = read_at<float>(bytes, 112);
  const float intercept = read_at<float>(bytes, 116);
  const std::int16_t qform_code = read_at<std::int16_t>(bytes, 252);
  const std::int16_t sform_code = read_at<std::int16_t>(bytes, 254);

  Eigen::Matrix4d A = Eigen::Matrix4d::Identity();
  if (sform_code > 0) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c)
        A(r, c) = read_at<float>(
            bytes, 280 + 16 * static_cast<std::size_t>(r) + 4 * static_cast<std::size_t>(c));
  } else if (qform_code > 0) {
    const double b = read_at<float>(bytes, 256), c = read_at<float>(bytes, 260),
                 d = read_at<float>(bytes, 264);
    const double a = std::sqrt(std::max(0.0, 1.0 - (b * b + c * c + d * d)));
    const Eigen::Matrix3d R = Eigen::Quaterniond(a, b, c, d).normalized().toRotationMatrix();
    const double qfac = pixdim[0] < 0 ? -1.0 : 1.0;
    A.topLeftCorner<3, 3>() =
        R * Eigen::Vector3d(pixdim[1], pixdim[2], qfac * pixdim[3]).asDiagonal();
    A(0, 3) = read_at<float>(bytes, 268);
    A(1, 3) = read_at<float>(bytes, 272);
    A(2, 3) = read_at<float>(bytes, 276);
  } else {
    A.topLeftCorner<3, 3>() = Eigen::Vector3d(pixdim[1], pixdim[2], pixdim[3]).asDiagonal();
  }
  if (!A.allFinite() || std::abs(A.topLeftCorner<3, 3>().determinant()) <= 0.0) {
    fail(path + ": the voxel-to-world transform is singular or not finite");
  }
  image.index_to_world = A;
  const std::size_t count = static_cast<std::size_t>(image.size.prod());
  convert(path, bytes, static_cast<std::size_t>(vox_offset), count, type->second, false,
          image.values);
  if (slope != 0.0f && std::isfinite(slope) && !(slope == 1.0f && intercept == 0.0f)) {
    for (float& v : image.values) v = slope * v + intercept;
  }
  return image;
}

VolumeImage read_inr(const std::string& path) {
  const std::vector<unsigned char> bytes = read_all(path);
  const std::string start = "#INRIMAGE-4#{";
  if (bytes.size() < 256 || std::memcmp(bytes.data(), start.data(), start.size()) != 0) {
    fail(path + ": not an INRIA image (no '#INRIMAGE-4#{' header)");
  }
  const std::string text(reinterpret_cast<const char*>(bytes.data()),
                         std::min<std::size_t>(bytes.size(), 4096));
  const std::size_t end = text.find("##}");
  if (end == std::string::npos) fail(path + ": INRIA header without its '##}' end");
  const std::size_t header_bytes = (end + 3 + 1 + 255) / 256 * 256;  // "##}\n", 256-byte blocks
  std::map<std::string, std::string> fields;
  std::istringstream lines(text.substr(0, end));
  for (std::string line; std::getline(lines, line);) {
    const std::size_t eq = line.find('=');
    if (eq != std::string::npos) fields[line.substr(0, eq)] = line.substr(eq + 1);
  }
  auto number = [&](const std::string& key, double fallback) {
    const auto it = fields.find(key);
    return it == fields.end() ? fallback : std::stod(it->second);
  };
  VolumeImage image;
  image.size =
      Eigen::Vector3i(static_cast<int>(number("XDIM", 0)), static_cast<int>(number("YDIM", 0)),
                      static_cast<int>(number("ZDIM", 0)));
  if ((image.size.array() <= 0).any()) fail(path + ": XDIM/YDIM/ZDIM missing or not positive");
  if (number("VDIM", 1) != 1) fail(path + ": VDIM is not 1 (vector images are not read)");
  const std::string kind = fields["TYPE"];
  const int bits = static_cast<int>(number("PIXSIZE", 8));  // "8 bits": stod reads the 8
  std::string type;
  if (kind == "unsigned fixed")
    type = bits == 8 ? "u8" : bits == 16 ? "u16" : bits == 32 ? "u32" : "";
  if (kind == "signed fixed")
    type = bits == 8 ? "i8" : bits == 16 ? "i16" : bits == 32 ? "i32" : "";
  if (kind == "float") type = bits == 32 ? "f32" : bits == 64 ? "f64" : "";
  if (type.empty())
    fail(path + ": unsupported INRIA TYPE '" + kind + "' with PIXSIZE " + std::to_string(bits));
  const std::string cpu = fields["CPU"];
  const bool big_endian = cpu == "sun" || cpu == "sgi";
  image.index_to_world.topLeftCorner<3, 3>() =
      Eigen::Vector3d(number("VX", 1), number("VY", 1), number("VZ", 1)).asDiagonal();
  image.index_to_world.topRightCorner<3, 1>() =
      Eigen::Vector3d(number("TX", 0), number("TY", 0), number("TZ", 0));
  convert(path, bytes, header_bytes, static_cast<std::size_t>(image.size.prod()), type, big_endian,
          image.values);
  return image;
}

}  // namespace

VolumeImageReadResult read_volume_image(const std::string& path) {
  return detail::guarded_read<VolumeImageReadResult>(path, [&]() {
    VolumeImageReadResult result;
    if (ends_with(path, ".nii") || ends_with(path, ".nii.gz")) {
      result.image = read_nifti(path);
    } else if (ends_with(path, ".inr") || ends_with(path, ".inr.gz")) {
      result.image = read_inr(path);
    } else {
      fail(path + ": unknown image format (expected .nii, .nii.gz, .inr or .inr.gz)");
    }
    return result;
  });
}

bool write_nifti(const std::string& path, const VolumeImage& image, std::string* error) {
  auto fail_write = [&](const std::string& message) {
    if (error != nullptr) *error = path + ": " + message;
    return false;
  };
  if (image.values.size() != static_cast<std::size_t>(image.size.prod())) {
    return fail_write("the number of values does not match the image size");
  }
  std::vector<unsigned char> header(352, 0);
  auto put16 = [&](std::size_t at, std::int16_t v) { std::memcpy(header.data() + at, &v, 2); };
  auto put32 = [&](std::size_t at, std::int32_t v) { std::memcpy(header.data() + at, &v, 4); };
  auto putf = [&](std::size_t at, float v) { std::memcpy(header.data() + at, &v, 4); };
  put32(0, 348);
  const std::int16_t dim[8] = {3,
                               static_cast<std::int16_t>(image.size.x()),
                               static_cast<std::int16_t>(image.size.y()),
                               static_cast<std::int16_t>(image.size.z()),
                               1,
                               1,
                               1,
                               1};
  for (int d = 0; d < 8; ++d) put16(40 + 2 * static_cast<std::size_t>(d), dim[d]);
  put16(70, 16);  // float32
  put16(72, 32);
  const Eigen::Vector3d spacing = image.spacing();
  putf(76, 1.0f);
  for (int d = 0; d < 3; ++d)
    putf(80 + 4 * static_cast<std::size_t>(d), static_cast<float>(spacing[d]));
  putf(108, 352.0f);
  putf(112, 1.0f);
  put16(254, 1);  // sform_code: scanner
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c)
      putf(280 + 16 * static_cast<std::size_t>(r) + 4 * static_cast<std::size_t>(c),
           static_cast<float>(image.index_to_world(r, c)));
  std::memcpy(header.data() + 344, "n+1", 4);
  const std::string tmp = path + ".tmp";
  const bool gzip = ends_with(path, ".gz");
  gzFile file = gzopen(tmp.c_str(), gzip ? "wb6" : "wbT");
  if (file == nullptr) return fail_write("cannot open for writing");
  const auto bytes = static_cast<unsigned>(image.values.size() * sizeof(float));
  const bool ok = gzwrite(file, header.data(), 352) == 352 &&
                  gzwrite(file, image.values.data(), bytes) == static_cast<int>(bytes);
  if (gzclose(file) != Z_OK || !ok) {
    std::remove(tmp.c_str());
    return fail_write("write failed");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    return fail_write("cannot rename the temporary file");
  return true;
}

}  // namespace sinew::offline::io
