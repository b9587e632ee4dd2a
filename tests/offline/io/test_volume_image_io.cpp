// Tests of offline/io/volume_image_io: NIfTI-1 (.nii, .nii.gz) and INRIA (.inr, .inr.gz) volumes.
// Synthetic files written here byte by byte (sform, qform and pixdim-only transforms, several
// datatypes, gzip) read back exactly; malformed files are one-line errors naming the file; the
// real TotalSegmentator masks and CGAL's liver image (../shared/data) read with their documented
// sizes and spacings (skipped without ../shared).

#include "offline/io/volume_image_io.hpp"

#include <gtest/gtest.h>
#include <zlib.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace sinew::offline::io {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir() {
  const fs::path dir = fs::temp_directory_path() / "sinew_volume_image_io";
  fs::create_directories(dir);
  return dir;
}

template <class T>
void put(std::vector<unsigned char>& bytes, std::size_t offset, T value) {
  std::memcpy(bytes.data() + offset, &value, sizeof(T));
}

// A 3x2x2 int16 NIfTI with value 10·i + j + 100·k; transform per `form` ("sform", "qform", "none").
std::vector<unsigned char> nifti_bytes(const std::string& form) {
  std::vector<unsigned char> bytes(352 + 12 * 2, 0);
  put<std::int32_t>(bytes, 0, 348);
  const std::int16_t dim[8] = {3, 3, 2, 2, 1, 1, 1, 1};
  for (int d = 0; d < 8; ++d)
    put<std::int16_t>(bytes, 40 + 2 * static_cast<std::size_t>(d), dim[d]);
  put<std::int16_t>(bytes, 70, 4);   // int16
  put<std::int16_t>(bytes, 72, 16);  // bitpix
  const float pixdim[8] = {1, 0.5f, 0.75f, 2, 0, 0, 0, 0};
  for (int d = 0; d < 8; ++d) put<float>(bytes, 76 + 4 * static_cast<std::size_t>(d), pixdim[d]);
  put<float>(bytes, 108, 352.0f);
  if (form == "sform") {
    put<std::int16_t>(bytes, 254, 1);
    const float rows[3][4] = {{-0.5f, 0, 0, 10}, {0, -0.75f, 0, 20}, {0, 0, 2, -30}};
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c)
        put<float>(bytes, 280 + 16 * static_cast<std::size_t>(r) + 4 * static_cast<std::size_t>(c),
                   rows[r][c]);
  } else if (form == "qform") {
    put<std::int16_t>(bytes, 252, 1);
    put<float>(bytes, 256, 0.0f);  // b, c, d = (0, 0, 1): 180° about z
    put<float>(bytes, 260, 0.0f);
    put<float>(bytes, 264, 1.0f);
    put<float>(bytes, 268, 1.0f);
    put<float>(bytes, 272, 2.0f);
    put<float>(bytes, 276, 3.0f);
  }
  std::memcpy(bytes.data() + 344, "n+1", 4);
  std::size_t v = 0;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 3; ++i)
        put<std::int16_t>(bytes, 352 + 2 * v++, static_cast<std::int16_t>(10 * i + j + 100 * k));
  return bytes;
}

void write(const fs::path& path, const std::vector<unsigned char>& bytes, bool gzip) {
  if (gzip) {
    gzFile f = gzopen(path.c_str(), "wb");
    gzwrite(f, bytes.data(), static_cast<unsigned>(bytes.size()));
    gzclose(f);
  } else {
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(bytes.data()),
               static_cast<std::streamsize>(bytes.size()));
  }
}

TEST(VolumeImageIo, NiftiTransformsAndValues) {
  for (const std::string form : {"sform", "qform", "none"}) {
    for (bool gzip : {false, true}) {
      const fs::path path = temp_dir() / (form + (gzip ? ".nii.gz" : ".nii"));
      write(path, nifti_bytes(form), gzip);
      const VolumeImageReadResult r = read_volume_image(path.string());
      ASSERT_TRUE(r.image.has_value()) << r.error;
      const VolumeImage& im = *r.image;
      EXPECT_EQ(im.size, Eigen::Vector3i(3, 2, 2));
      EXPECT_EQ(im.at(2, 1, 1), 121.0f);
      EXPECT_EQ(im.at(1, 0, 0), 10.0f);
      Eigen::Vector3d expected = Eigen::Vector3d::Zero();
      if (form == "sform") expected = Eigen::Vector3d(-0.5 * 2 + 10, -0.75 * 1 + 20, 2 * 1 - 30);
      if (form == "qform") expected = Eigen::Vector3d(-0.5 * 2 + 1, -0.75 * 1 + 2, 2 * 1 + 3);
      if (form == "none") expected = Eigen::Vector3d(0.5 * 2, 0.75 * 1, 2 * 1);
      EXPECT_LT((im.world(Eigen::Vector3d(2, 1, 1)) - expected).norm(), 1e-6) << form;
      EXPECT_LT((im.spacing() - Eigen::Vector3d(0.5, 0.75, 2)).norm(), 1e-6) << form;
    }
  }
}

TEST(VolumeImageIo, InrHeaderAndData) {
  std::string header =
      "#INRIMAGE-4#{\nXDIM=3\nYDIM=2\nZDIM=2\nVDIM=1\nTYPE=unsigned fixed\nPIXSIZE=8 bits\n"
      "SCALE=2**0\nCPU=decm\nVX=0.5\nVY=0.75\nVZ=2\n";
  header += std::string(256 - header.size() - 4, '\n') + "##}\n";
  std::vector<unsigned char> bytes(header.begin(), header.end());
  for (int v = 0; v < 12; ++v) bytes.push_back(static_cast<unsigned char>(v == 7 ? 255 : 0));
  const fs::path path = temp_dir() / "mask.inr.gz";
  write(path, bytes, true);
  const VolumeImageReadResult r = read_volume_image(path.string());
  ASSERT_TRUE(r.image.has_value()) << r.error;
  EXPECT_EQ(r.image->size, Eigen::Vector3i(3, 2, 2));
  EXPECT_EQ(r.image->at(1, 0, 1), 255.0f);  // voxel 7 = i 1, j 0, k 1
  EXPECT_LT((r.image->spacing() - Eigen::Vector3d(0.5, 0.75, 2)).norm(), 1e-12);
}

TEST(VolumeImageIo, MalformedFilesAreOneLineErrors) {
  auto error_of = [&](const std::string& name, std::vector<unsigned char> bytes) {
    const fs::path path = temp_dir() / name;
    write(path, bytes, false);
    const VolumeImageReadResult r = read_volume_image(path.string());
    EXPECT_FALSE(r.image.has_value());
    EXPECT_EQ(r.error.find('\n'), std::string::npos);
    EXPECT_EQ(r.error.rfind(path.string(), 0), 0u) << r.error;
    return r.error;
  };
  std::vector<unsigned char> truncated = nifti_bytes("sform");
  truncated.resize(truncated.size() - 5);
  EXPECT_NE(error_of("truncated.nii", truncated).find("truncated voxel data"), std::string::npos);
  std::vector<unsigned char> four_d = nifti_bytes("sform");
  put<std::int16_t>(four_d, 40, 4);
  put<std::int16_t>(four_d, 48, 5);
  EXPECT_NE(error_of("4d.nii", four_d).find("only 3D volumes"), std::string::npos);
  std::vector<unsigned char> bad_type = nifti_bytes("sform");
  put<std::int16_t>(bad_type, 70, 1536);
  EXPECT_NE(error_of("type.nii", bad_type).find("unsupported NIfTI datatype 1536"),
            std::string::npos);
  EXPECT_NE(error_of("short.nii", std::vector<unsigned char>(10, 0)).find("348-byte header"),
            std::string::npos);
  EXPECT_NE(error_of("image.png", nifti_bytes("sform")).find("unknown image format"),
            std::string::npos);
  EXPECT_NE(read_volume_image((temp_dir() / "missing.nii").string()).error.find("cannot open"),
            std::string::npos);
}

TEST(VolumeImageIoRealData, TotalSegmentatorMaskAndCgalLiver) {
  const fs::path data = fs::path(SINEW_SHARED_DIR) / "data";
  const fs::path mask = data / "totalsegmentator_ct" / "gluteus_medius_left.nii.gz";
  if (!fs::exists(mask)) GTEST_SKIP() << "no " << mask;
  const VolumeImageReadResult r = read_volume_image(mask.string());
  ASSERT_TRUE(r.image.has_value()) << r.error;
  long inside = 0;
  for (float v : r.image->values) inside += v > 0.5f;
  std::printf("gluteus_medius_left: %d x %d x %d voxels of %.3f x %.3f x %.3f mm, %ld inside\n",
              r.image->size.x(), r.image->size.y(), r.image->size.z(), r.image->spacing().x(),
              r.image->spacing().y(), r.image->spacing().z(), inside);
  EXPECT_NEAR(r.image->spacing().x(), 3.0, 0.01);  // "3 mm voxels" (data README)
  EXPECT_GT(inside, 1000);
  const fs::path liver = data / "liver_image" / "liver.inr.gz";
  const VolumeImageReadResult l = read_volume_image(liver.string());
  ASSERT_TRUE(l.image.has_value()) << l.error;
  EXPECT_EQ(l.image->size, Eigen::Vector3i(438, 353, 329));
  EXPECT_NEAR(l.image->spacing().x(), 0.62, 0.01);
  EXPECT_NEAR(l.image->spacing().z(), 0.67, 0.01);
}

}  // namespace
}  // namespace sinew::offline::io
