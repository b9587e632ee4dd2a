#pragma once
/// sinew-track --whiskers --hdf5 FILE: the whisker table and the full centrelines in one HDF5 file
/// (Debian's libhdf5), appended frame by frame (a long high-speed recording is never held in
/// memory) and renamed into place when complete:
///   /summary                   one row per whisker per frame, the columns of the CSV table
///                              (compound: frame, id, status as a 16-byte string, then doubles;
///                              NaN where a value is absent)
///   /frame                     the frame index of each centreline row
///   /centrelines/whisker_<id>  [frames, nodes, 3]: x, y (pixels) and θ of every node
/// Attributes on the root: the read-out's units and options. In Python:
///   import h5py, pandas as pd
///   f = h5py.File("w.h5")
///   d = pd.DataFrame(f["summary"][:])
///   d["status"] = d.status.str.decode("ascii")
///   c = f["centrelines/whisker_0"][:]  # (frames, nodes, 3)

#include <memory>
#include <string>
#include <vector>

namespace sinew::tools {

class WhiskerHdf5Writer {
 public:
  /// value_columns: the names of the summary's double columns (after frame, id, status);
  /// nodes[w]: whisker w's node count. Throws InputError when the file cannot be created.
  WhiskerHdf5Writer(const std::string& path, const std::vector<std::string>& value_columns,
                    const std::vector<int>& nodes);
  ~WhiskerHdf5Writer();
  WhiskerHdf5Writer(const WhiskerHdf5Writer&) = delete;
  WhiskerHdf5Writer& operator=(const WhiskerHdf5Writer&) = delete;

  /// A string attribute on the root group (units, options).
  void attribute(const std::string& name, const std::string& value);
  /// One whisker's row of a frame: values in value_columns' order.
  void add_row(int frame, int id, const std::string& status, const std::vector<double>& values);
  /// Every whisker's nodes on a frame: centrelines[w] holds 3 · nodes[w] numbers (x, y, θ).
  void add_frame(int frame, const std::vector<std::vector<double>>& centrelines);
  /// Flushes, closes and renames the file into place. Throws InputError on failure.
  void finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sinew::tools
