#include "tools/track/whisker_hdf5.hpp"

#include <hdf5.h>

#include <cstring>
#include <filesystem>

#include "tools/io/json_file.hpp"

namespace sinew::tools {

namespace {

constexpr std::size_t kStatusBytes = 16;

// Appends `count` records of `memtype` to the extendible 1-D dataset.
void append_1d(hid_t dataset, hid_t memtype, const void* data, hsize_t count) {
  hid_t space = H5Dget_space(dataset);
  hsize_t size = 0;
  H5Sget_simple_extent_dims(space, &size, nullptr);
  H5Sclose(space);
  const hsize_t extent = size + count;
  H5Dset_extent(dataset, &extent);
  space = H5Dget_space(dataset);
  H5Sselect_hyperslab(space, H5S_SELECT_SET, &size, nullptr, &count, nullptr);
  hid_t mem = H5Screate_simple(1, &count, nullptr);
  H5Dwrite(dataset, memtype, mem, space, H5P_DEFAULT, data);
  H5Sclose(mem);
  H5Sclose(space);
}

hid_t extendible(hid_t parent, const char* name, hid_t type, int rank, const hsize_t* dims,
                 const hsize_t* chunk) {
  std::vector<hsize_t> zero(dims, dims + rank), max(dims, dims + rank);
  zero[0] = 0;
  max[0] = H5S_UNLIMITED;
  hid_t space = H5Screate_simple(rank, zero.data(), max.data());
  hid_t props = H5Pcreate(H5P_DATASET_CREATE);
  H5Pset_chunk(props, rank, chunk);
  H5Pset_deflate(props, 4);
  hid_t d = H5Dcreate2(parent, name, type, space, H5P_DEFAULT, props, H5P_DEFAULT);
  H5Pclose(props);
  H5Sclose(space);
  return d;
}

}  // namespace

struct WhiskerHdf5Writer::Impl {
  std::string path, tmp;
  hid_t file = -1, summary = -1, frames = -1, row_type = -1, status_type = -1;
  std::vector<hid_t> centrelines;
  std::vector<int> nodes;
  std::size_t values = 0, row_bytes = 0;
  std::vector<char> row;
};

WhiskerHdf5Writer::WhiskerHdf5Writer(const std::string& path,
                                     const std::vector<std::string>& value_columns,
                                     const std::vector<int>& nodes)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.path = path;
  m.tmp = path + ".tmp";
  m.nodes = nodes;
  m.values = value_columns.size();
  m.file = H5Fcreate(m.tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (m.file < 0) throw InputError(path + ": cannot create the HDF5 file");
  // The summary row: int32 frame, int32 id, char[16] status, doubles.
  m.status_type = H5Tcopy(H5T_C_S1);
  H5Tset_size(m.status_type, kStatusBytes);
  m.row_bytes = 2 * sizeof(int) + kStatusBytes + m.values * sizeof(double);
  m.row_type = H5Tcreate(H5T_COMPOUND, m.row_bytes);
  H5Tinsert(m.row_type, "frame", 0, H5T_NATIVE_INT);
  H5Tinsert(m.row_type, "id", sizeof(int), H5T_NATIVE_INT);
  H5Tinsert(m.row_type, "status", 2 * sizeof(int), m.status_type);
  for (std::size_t k = 0; k < m.values; ++k) {
    H5Tinsert(m.row_type, value_columns[k].c_str(),
              2 * sizeof(int) + kStatusBytes + k * sizeof(double), H5T_NATIVE_DOUBLE);
  }
  m.row.resize(m.row_bytes);
  const hsize_t one = 1, chunk_rows = 1024;
  m.summary = extendible(m.file, "summary", m.row_type, 1, &one, &chunk_rows);
  m.frames = extendible(m.file, "frame", H5T_NATIVE_INT, 1, &one, &chunk_rows);
  hid_t group = H5Gcreate2(m.file, "centrelines", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  for (std::size_t w = 0; w < nodes.size(); ++w) {
    const hsize_t dims[3] = {1, static_cast<hsize_t>(nodes[w]), 3};
    const hsize_t chunk[3] = {256, static_cast<hsize_t>(nodes[w]), 3};
    const std::string name = "whisker_" + std::to_string(w);
    m.centrelines.push_back(extendible(group, name.c_str(), H5T_NATIVE_DOUBLE, 3, dims, chunk));
  }
  H5Gclose(group);
  if (m.summary < 0 || m.frames < 0) throw InputError(path + ": cannot create the HDF5 datasets");
}

WhiskerHdf5Writer::~WhiskerHdf5Writer() {
  if (!impl_ || impl_->file < 0) return;
  Impl& m = *impl_;
  for (hid_t d : m.centrelines) H5Dclose(d);
  H5Dclose(m.summary);
  H5Dclose(m.frames);
  H5Tclose(m.row_type);
  H5Tclose(m.status_type);
  H5Fclose(m.file);
  // Not finished (an error on the way): the partial file is not left as if complete.
  std::error_code ec;
  std::filesystem::remove(m.tmp, ec);
}

void WhiskerHdf5Writer::attribute(const std::string& name, const std::string& value) {
  Impl& m = *impl_;
  hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, std::max<std::size_t>(value.size(), 1));
  hid_t space = H5Screate(H5S_SCALAR);
  hid_t a = H5Acreate2(m.file, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT);
  H5Awrite(a, type, value.c_str());
  H5Aclose(a);
  H5Sclose(space);
  H5Tclose(type);
}

void WhiskerHdf5Writer::add_row(int frame, int id, const std::string& status,
                                const std::vector<double>& values) {
  Impl& m = *impl_;
  char* p = m.row.data();
  std::memcpy(p, &frame, sizeof(int));
  std::memcpy(p + sizeof(int), &id, sizeof(int));
  std::memset(p + 2 * sizeof(int), 0, kStatusBytes);
  std::memcpy(p + 2 * sizeof(int), status.data(), std::min(status.size(), kStatusBytes - 1));
  std::memcpy(p + 2 * sizeof(int) + kStatusBytes, values.data(),
              std::min(values.size(), m.values) * sizeof(double));
  append_1d(m.summary, m.row_type, p, 1);
}

void WhiskerHdf5Writer::add_frame(int frame, const std::vector<std::vector<double>>& centrelines) {
  Impl& m = *impl_;
  append_1d(m.frames, H5T_NATIVE_INT, &frame, 1);
  for (std::size_t w = 0; w < m.centrelines.size() && w < centrelines.size(); ++w) {
    const hid_t d = m.centrelines[w];
    hid_t space = H5Dget_space(d);
    hsize_t dims[3];
    H5Sget_simple_extent_dims(space, dims, nullptr);
    H5Sclose(space);
    const hsize_t extent[3] = {dims[0] + 1, dims[1], 3};
    H5Dset_extent(d, extent);
    space = H5Dget_space(d);
    const hsize_t start[3] = {dims[0], 0, 0}, count[3] = {1, dims[1], 3};
    H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr);
    hid_t mem = H5Screate_simple(3, count, nullptr);
    H5Dwrite(d, H5T_NATIVE_DOUBLE, mem, space, H5P_DEFAULT, centrelines[w].data());
    H5Sclose(mem);
    H5Sclose(space);
  }
}

void WhiskerHdf5Writer::finish() {
  Impl& m = *impl_;
  for (hid_t d : m.centrelines) H5Dclose(d);
  m.centrelines.clear();
  H5Dclose(m.summary);
  H5Dclose(m.frames);
  H5Tclose(m.row_type);
  H5Tclose(m.status_type);
  const herr_t closed = H5Fclose(m.file);
  m.file = -1;
  if (closed < 0) throw InputError(m.path + ": writing the HDF5 file failed");
  std::error_code ec;
  std::filesystem::rename(m.tmp, m.path, ec);
  if (ec) throw InputError(m.path + ": cannot rename " + m.tmp + " into place: " + ec.message());
}

}  // namespace sinew::tools
