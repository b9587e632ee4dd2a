#include "tools/track/whisker_chunks.hpp"

#include <hdf5.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/videoio.hpp>
#include <sstream>
#include <tuple>

#include "tools/io/csv_fields.hpp"
#include "tools/io/json_file.hpp"
#include "tools/track/whisker_hdf5.hpp"

namespace sinew::tools {
namespace {

namespace fs = std::filesystem;
constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

// One chunk's results.jsonl, a line at a time: its detection line, then its frame lines in order
// of frame (as sinew-track writes them). Only what the stitching needs is ever held: a long
// high-speed recording's results do not fit in memory as JSON values (~14 bytes per byte of text).
class ChunkLines {
 public:
  explicit ChunkLines(fs::path file) : file_(std::move(file)), in_(file_) {
    if (!in_) throw InputError(file_.string() + ": cannot open a chunk's results");
    if (!read(detection_) || !detection_.contains("detection"))
      throw InputError(where() + ": no detection line before the frames");
  }
  const nlohmann::json& detection() const { return detection_; }
  /// The next frame line and its frame; false at the end.
  bool next(nlohmann::json& line, int& frame) {
    if (!read(line)) return false;
    if (!line.contains("frame") || !line.contains("whiskers"))
      throw InputError(where() + ": not a frame line");
    frame = line.at("frame").get<int>();
    if (frame <= last_frame_)
      throw InputError(where() + ": frame " + std::to_string(frame) + " after frame " +
                       std::to_string(last_frame_));
    last_frame_ = frame;
    return true;
  }

 private:
  std::string where() const { return file_.string() + ":" + std::to_string(number_); }
  bool read(nlohmann::json& j) {
    std::string text;
    while (std::getline(in_, text)) {
      ++number_;
      if (text.empty()) continue;
      try {
        j = nlohmann::json::parse(text);
      } catch (const std::exception& e) {
        throw InputError(where() + ": not JSON: " + e.what());
      }
      return true;
    }
    return false;
  }

  fs::path file_;
  std::ifstream in_;
  nlohmann::json detection_;
  int number_ = 0;
  int last_frame_ = std::numeric_limits<int>::min();
};

// Frame lines by frame index.
using FrameLines = std::map<int, nlohmann::json>;

using Curve = std::vector<std::array<double, 2>>;

Curve curve_of(const nlohmann::json& whisker) {
  Curve c;
  for (const auto& n : whisker.at("nodes")) c.push_back({n[0].get<double>(), n[1].get<double>()});
  return c;
}

// Mean distance from a's nodes to the polyline b, over the nodes whose nearest point on b is not
// one of b's ends (the part the two curves share: tracked lengths differ); NaN when none is.
double one_sided(const Curve& a, const Curve& b) {
  double sum = 0.0;
  int n = 0;
  for (const auto& p : a) {
    double best = std::numeric_limits<double>::infinity();
    bool interior = false;
    for (std::size_t i = 0; i + 1 < b.size(); ++i) {
      const double ex = b[i + 1][0] - b[i][0], ey = b[i + 1][1] - b[i][1];
      const double len2 = ex * ex + ey * ey;
      double t = len2 > 0 ? ((p[0] - b[i][0]) * ex + (p[1] - b[i][1]) * ey) / len2 : 0.0;
      const bool end = (i == 0 && t < 0) || (i + 2 == b.size() && t > 1);
      t = std::clamp(t, 0.0, 1.0);
      const double dx = b[i][0] + t * ex - p[0], dy = b[i][1] + t * ey - p[1];
      const double d = std::hypot(dx, dy);
      if (d < best) {
        best = d;
        interior = !end;
      }
    }
    if (interior) {
      sum += best;
      ++n;
    }
  }
  return n > 0 ? sum / n : kNan;
}

// The distance between two curves of a whisker: the mean of both one-sided distances.
double curve_distance(const Curve& a, const Curve& b) {
  const double ab = one_sided(a, b), ba = one_sided(b, a);
  if (std::isnan(ab)) return ba;
  if (std::isnan(ba)) return ab;
  return 0.5 * (ab + ba);
}

bool tracked(const nlohmann::json& w) {
  const std::string s = w.at("status").get<std::string>();
  return s != "lost" && !w.at("nodes").empty();
}

// A follicle's position along the face edge: y for a face on the left or right, else x.
double along_face(const nlohmann::json& whisker, bool vertical_edge) {
  return whisker.at("follicle")[vertical_edge ? 1 : 0].get<double>();
}

// Whiskers of the chunk that no stitched whisker's curve matched over the overlap (the stitched
// one was not tracked there: a chunk before this one did not find it): by follicle order along the
// face, which whiskers keep. A chunk whisker whose nearest matched neighbours on either side along
// the face enclose exactly one free stitched id (at its last tracked frame, `last`) takes that id.
// `overlap`: the chunk's frames before its output_from.
void match_by_order(const std::map<int, double>& last, const FrameLines& overlap,
                    bool vertical_edge, ChunkStitch& m, std::vector<bool>& taken) {
  if (overlap.empty()) return;
  std::vector<std::pair<double, int>>
      order;  // (along the face, chunk id) on its last overlap frame
  for (const auto& w : overlap.rbegin()->second.at("whiskers")) {
    if (tracked(w)) order.emplace_back(along_face(w, vertical_edge), w.at("id").get<int>());
  }
  std::sort(order.begin(), order.end());
  for (std::size_t k = 0; k < order.size(); ++k) {
    const int q = order[k].second;
    if (m.stitched_id[q] >= 0) continue;
    double lo = -std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t j = k; j-- > 0;) {
      const int p = m.stitched_id[order[j].second];
      if (p >= 0 && last.count(p)) {
        lo = last.at(p);
        break;
      }
    }
    for (std::size_t j = k + 1; j < order.size(); ++j) {
      const int p = m.stitched_id[order[j].second];
      if (p >= 0 && last.count(p)) {
        hi = last.at(p);
        break;
      }
    }
    std::vector<int> free;
    for (const auto& [p, s] : last) {
      if (!taken[p] && s > lo && s < hi) free.push_back(p);
    }
    if (free.size() == 1) {
      m.stitched_id[q] = free.front();
      taken[free.front()] = true;
    }
  }
}

// Stitched ids for the chunk's whiskers (ids 0 .. chunk_ids − 1) from the stitched frames over the
// overlap's second half (`stitched`: the stitched frames before the chunk's output_from, at least
// those of its overlap; `overlap`: the chunk's own frames there).
ChunkStitch match_ids(const FrameLines& stitched, const FrameLines& overlap, int chunk_ids,
                      const std::map<int, double>& last, const WhiskerChunk& plan,
                      bool vertical_edge, int& next_id) {
  const int from = plan.first + (plan.output_from - plan.first) / 2;
  std::map<std::pair<int, int>, std::pair<double, int>> sums;  // (chunk id, stitched id)
  for (const auto& [frame, line] : overlap) {
    if (frame < from || frame >= plan.output_from) continue;
    const auto s = stitched.find(frame);
    if (s == stitched.end()) continue;
    for (const auto& q : line.at("whiskers")) {
      if (!tracked(q)) continue;
      const Curve cq = curve_of(q);
      for (const auto& p : s->second.at("whiskers")) {
        if (!tracked(p)) continue;
        const double d = curve_distance(cq, curve_of(p));
        if (std::isnan(d)) continue;
        auto& acc = sums[{q.at("id").get<int>(), p.at("id").get<int>()}];
        acc.first += d;
        ++acc.second;
      }
    }
  }
  // The closest pairs first, each id once, within the gate.
  std::vector<std::tuple<double, int, int>> pairs;
  for (const auto& [ids, acc] : sums)
    pairs.emplace_back(acc.first / acc.second, ids.first, ids.second);
  std::sort(pairs.begin(), pairs.end());
  ChunkStitch m;
  m.stitched_id.assign(static_cast<std::size_t>(chunk_ids), -1);
  m.distance_px.assign(static_cast<std::size_t>(chunk_ids), kNan);
  std::vector<bool> taken(static_cast<std::size_t>(next_id), false);
  for (const auto& [d, q, p] : pairs) {
    if (d > kStitchGatePx || m.stitched_id[q] >= 0 || taken[p]) continue;
    m.stitched_id[q] = p;
    m.distance_px[q] = d;
    taken[p] = true;
  }
  match_by_order(last, overlap, vertical_edge, m, taken);
  for (int& id : m.stitched_id) {
    if (id < 0) id = next_id++;
  }
  return m;
}

bool is_rest_relative(const std::string& key) {
  return key.rfind("delta_curvature", 0) == 0 ||
         (key.rfind("m0_", 0) == 0 && key.find("_sd") == std::string::npos);
}

using RestOffsets = std::map<std::pair<int, std::string>, double>;

// Per stitched id and rest-relative key, the mean of (stitched − chunk) over the overlap frames
// where both have it: the two rest shapes' difference, added to the chunk's values.
RestOffsets rest_offsets(const FrameLines& stitched, const FrameLines& overlap,
                         const WhiskerChunk& plan, const ChunkStitch& ids) {
  std::map<std::pair<int, std::string>, std::pair<double, int>> sums;
  const int from = plan.first + (plan.output_from - plan.first) / 2;
  for (const auto& [frame, line] : overlap) {
    if (frame >= plan.output_from) break;
    if (frame < from) continue;  // the chunk's rest shape is being set
    const auto s = stitched.find(frame);
    if (s == stitched.end()) continue;
    for (const auto& q : line.at("whiskers")) {
      const int id = ids.stitched_id[q.at("id").get<int>()];
      for (const auto& p : s->second.at("whiskers")) {
        if (p.at("id").get<int>() != id) continue;
        for (const auto& [key, value] : q.items()) {
          if (!is_rest_relative(key) || !value.is_number() || !p.contains(key)) continue;
          auto& acc = sums[{id, key}];
          acc.first += p.at(key).get<double>() - value.get<double>();
          ++acc.second;
        }
      }
    }
  }
  RestOffsets offsets;
  for (const auto& [k, acc] : sums) offsets[k] = acc.first / acc.second;
  return offsets;
}

// A chunk's frame line with its ids and rest-relative values stitched.
void stitch_line(nlohmann::json& line, const ChunkStitch& ids, const RestOffsets& offsets) {
  for (auto& w : line.at("whiskers")) {
    const int id = ids.stitched_id.at(w.at("id").get<int>());
    w["id"] = id;
    for (auto& [key, value] : w.items()) {
      const auto o = offsets.find({id, key});
      if (o != offsets.end() && value.is_number()) value = value.get<double>() + o->second;
    }
  }
}

std::string read_attribute(hid_t file, const char* name) {
  if (H5Aexists(file, name) <= 0) return "";
  const hid_t a = H5Aopen(file, name, H5P_DEFAULT);
  const hid_t type = H5Aget_type(a);
  std::string value(H5Tget_size(type), '\0');
  H5Aread(a, type, value.data());
  H5Tclose(type);
  H5Aclose(a);
  value.resize(std::strlen(value.c_str()));
  return value;
}

}  // namespace

int count_input_frames(const std::string& input) {
  std::error_code ec;
  if (fs::is_directory(input, ec)) {
    int n = 0;
    for (const auto& e : fs::directory_iterator(input, ec)) n += e.is_regular_file();
    return n;
  }
  if (input.find('%') != std::string::npos) {
    int n = 0;
    for (char name[4096];; ++n) {
      std::snprintf(name, sizeof name, input.c_str(), n);
      if (!fs::exists(name, ec)) return n;
    }
  }
  cv::VideoCapture capture(input);
  if (!capture.isOpened()) throw InputError(input + ": cannot open the video");
  return static_cast<int>(capture.get(cv::CAP_PROP_FRAME_COUNT));
}

std::vector<WhiskerChunk> plan_whisker_chunks(int first, int frames, int chunks, int overlap) {
  const int n = std::max(1, std::min(chunks, frames / std::max(1, 2 * overlap)));
  std::vector<WhiskerChunk> plan;
  for (int c = 0; c < n; ++c) {
    const int begin = first + static_cast<int>(static_cast<long>(frames) * c / n);
    const int end = first + static_cast<int>(static_cast<long>(frames) * (c + 1) / n);
    WhiskerChunk k;
    k.output_from = begin;
    k.first = c == 0 ? begin : begin - overlap;
    k.count = c + 1 == n ? -1 : end - k.first;
    plan.push_back(k);
  }
  return plan;
}

std::vector<ChunkStitch> stitch_whisker_chunks(const std::vector<std::string>& chunk_dirs,
                                               const std::vector<WhiskerChunk>& chunks,
                                               const std::string& out_dir, bool table, bool hdf5) {
  const fs::path out(out_dir);
  const std::size_t n = chunk_dirs.size();
  // The first frame a chunk does not contribute: the next chunk's output_from.
  const auto end_of = [&](std::size_t c) {
    return c + 1 < n ? chunks[c + 1].output_from : std::numeric_limits<int>::max();
  };
  const auto results_of = [&](std::size_t c) { return fs::path(chunk_dirs[c]) / "results.jsonl"; };

  // Pass 1, chunk by chunk: the id mapping and the rest offsets. Held at any time: one chunk's
  // overlap frames and the stitched frames the next chunk's overlap covers, not the results.
  std::vector<ChunkStitch> stitches;
  std::vector<RestOffsets> offsets(n);
  nlohmann::json detection;
  bool vertical = true;
  int next_id = 0;
  FrameLines tail;              // stitched frames within the next chunk's overlap
  std::map<int, double> last;   // stitched id → its follicle along the face when last tracked
  std::map<int, int> node_max;  // stitched id → its most nodes on a stitched frame
  for (std::size_t c = 0; c < n; ++c) {
    ChunkLines lines(results_of(c));
    if (c == 0) {
      detection = lines.detection();
      for (const auto& w : detection.at("detection").at("whiskers"))
        next_id = std::max(next_id, w.at("id").get<int>() + 1);
      const nlohmann::json& face = detection.at("detection").at("face");
      vertical = !face.is_string() || face.get_ref<const std::string&>() == "left" ||
                 face.get_ref<const std::string&>() == "right";
    }
    const int end = end_of(c);
    const int next_first = c + 1 < n ? chunks[c + 1].first : end;
    FrameLines overlap, next_tail;
    std::map<int, double> chunk_last;  // by the chunk's ids
    std::map<int, int> chunk_nodes;
    int chunk_ids = 0;
    nlohmann::json line;
    int frame = 0;
    while (lines.next(line, frame)) {
      for (const auto& w : line.at("whiskers"))
        chunk_ids = std::max(chunk_ids, w.at("id").get<int>() + 1);
      if (frame < chunks[c].output_from) {
        overlap[frame] = std::move(line);
        continue;
      }
      if (frame >= end) continue;
      for (const auto& w : line.at("whiskers")) {
        const int q = w.at("id").get<int>();
        int& k = chunk_nodes[q];
        k = std::max(k, static_cast<int>(w.at("nodes").size()));
        if (tracked(w)) chunk_last[q] = along_face(w, vertical);
      }
      if (frame >= next_first) next_tail[frame] = std::move(line);
    }
    ChunkStitch ids;
    if (c == 0) {
      next_id = std::max(next_id, chunk_ids);
      ids.stitched_id.resize(static_cast<std::size_t>(next_id));
      for (int i = 0; i < next_id; ++i) ids.stitched_id[i] = i;
      ids.distance_px.assign(static_cast<std::size_t>(next_id), 0.0);
    } else {
      ids = match_ids(tail, overlap, chunk_ids, last, chunks[c], vertical, next_id);
      offsets[c] = rest_offsets(tail, overlap, chunks[c], ids);
    }
    for (const auto& [q, along] : chunk_last) last[ids.stitched_id.at(q)] = along;
    for (const auto& [q, k] : chunk_nodes) {
      int& m = node_max[ids.stitched_id.at(q)];
      m = std::max(m, k);
    }
    for (auto& [f, l] : next_tail) stitch_line(l, ids, offsets[c]);
    tail = std::move(next_tail);
    stitches.push_back(std::move(ids));
  }
  tail.clear();

  nlohmann::json record = nlohmann::json::array();
  for (std::size_t c = 0; c < chunks.size(); ++c) {
    nlohmann::json distances = nlohmann::json::array();
    for (double d : stitches[c].distance_px)
      distances.push_back(std::isnan(d) ? nlohmann::json(nullptr) : nlohmann::json(d));
    record.push_back({{"first", chunks[c].first},
                      {"output_from", chunks[c].output_from},
                      {"ids", stitches[c].stitched_id},
                      {"distance_px", distances}});
  }
  detection["detection"]["chunks"] = record;

  // Pass 2: every file written a frame at a time, each chunk's frames from its output_from to the
  // next chunk's, ids and rest-relative values stitched.
  std::ofstream json(out / "results.jsonl.tmp", std::ios::trunc);
  json << detection.dump() << "\n";
  std::vector<std::string> header;
  std::ofstream csv;
  if (table) {
    const fs::path first = fs::path(chunk_dirs[0]) / "whiskers.csv";
    std::ifstream in(first);
    std::string line;
    if (!in || !std::getline(in, line))
      throw InputError(first.string() + ": cannot open a chunk's table");
    header = split_csv_fields(line);
    csv.open(out / "whiskers.csv.tmp", std::ios::trunc);
    for (std::size_t k = 0; k < header.size(); ++k) csv << (k ? "," : "") << header[k];
    csv << "\n";
  }
  // The HDF5 file: a whisker's centreline rows have its largest node count over the chunks (a
  // chunk's detection may give it fewer nodes), NaN-padded.
  std::unique_ptr<WhiskerHdf5Writer> writer;
  std::vector<int> node_counts(static_cast<std::size_t>(next_id), 1);
  for (const auto& [id, k] : node_max) node_counts[id] = std::max(1, k);
  const std::size_t values_count = header.size() > 3 ? header.size() - 3 : 0;
  if (table && hdf5) {
    const std::string first = (fs::path(chunk_dirs[0]) / "whiskers.h5").string();
    const hid_t f = H5Fopen(first.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0) throw InputError(first + ": cannot open a chunk's HDF5 file");
    const std::string source = read_attribute(f, "source"), units = read_attribute(f, "units"),
                      readout = read_attribute(f, "readout");
    H5Fclose(f);
    const std::vector<std::string> value_columns(header.begin() + 3, header.end());
    writer = std::make_unique<WhiskerHdf5Writer>((out / "whiskers.h5").string(), value_columns,
                                                 node_counts);
    writer->attribute("source", source);
    writer->attribute("units", units);
    writer->attribute("readout", readout);
    writer->attribute("chunks", record.dump());
  }
  std::vector<std::vector<double>> centrelines(static_cast<std::size_t>(next_id));
  std::vector<double> values(values_count);
  // One frame's table rows, sorted by id, into the table and the HDF5 file.
  std::vector<std::vector<std::string>> rows;
  const auto flush_rows = [&] {
    std::stable_sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) {
      return std::stoi(a[1]) < std::stoi(b[1]);
    });
    for (const auto& f : rows) {
      for (std::size_t k = 0; k < f.size(); ++k) csv << (k ? "," : "") << f[k];
      csv << "\n";
      if (!writer) continue;
      for (std::size_t k = 0; k < values.size(); ++k)
        values[k] = k + 3 < f.size() && !f[k + 3].empty() ? std::stod(f[k + 3]) : kNan;
      writer->add_row(std::stoi(f[0]), std::stoi(f[1]), f[2], values);
    }
    rows.clear();
  };
  for (std::size_t c = 0; c < n; ++c) {
    const int end = end_of(c);
    ChunkLines lines(results_of(c));
    nlohmann::json line;
    int frame = 0;
    while (lines.next(line, frame)) {
      if (frame < chunks[c].output_from || frame >= end) continue;
      stitch_line(line, stitches[c], offsets[c]);
      json << line.dump() << "\n";
      if (!writer) continue;
      for (int id = 0; id < next_id; ++id) centrelines[id].assign(3 * node_counts[id], kNan);
      for (const auto& w : line.at("whiskers")) {
        if (w.at("status").get<std::string>() == "lost") continue;
        std::vector<double>& cl = centrelines[w.at("id").get<int>()];
        const auto& nodes = w.at("nodes");
        for (std::size_t i = 0; i < nodes.size() && 3 * i + 2 < cl.size(); ++i) {
          for (int k = 0; k < 3; ++k) cl[3 * i + k] = nodes[i][k].get<double>();
        }
      }
      writer->add_frame(frame, centrelines);
    }
    if (!table) continue;
    const fs::path file = fs::path(chunk_dirs[c]) / "whiskers.csv";
    std::ifstream in(file);
    std::string text;
    if (!in || !std::getline(in, text))
      throw InputError(file.string() + ": cannot open a chunk's table");
    int row_frame = std::numeric_limits<int>::min();
    while (std::getline(in, text)) {
      std::vector<std::string> f = split_csv_fields(text);
      if (f.size() < 3) continue;
      const int fr = std::stoi(f[0]);
      if (fr < chunks[c].output_from || fr >= end) continue;
      if (fr != row_frame) {
        flush_rows();
        row_frame = fr;
      }
      const int id = stitches[c].stitched_id.at(std::stoi(f[1]));
      f[1] = std::to_string(id);
      for (std::size_t k = 3; k < f.size() && k < header.size(); ++k) {
        const auto o = offsets[c].find({id, header[k]});
        if (o != offsets[c].end() && !f[k].empty()) {
          std::ostringstream v;
          v.precision(9);
          v << std::stod(f[k]) + o->second;
          f[k] = v.str();
        }
      }
      rows.push_back(std::move(f));
    }
    flush_rows();
  }
  json.close();
  if (!json) throw InputError((out / "results.jsonl").string() + ": cannot write");
  fs::rename(out / "results.jsonl.tmp", out / "results.jsonl");
  if (!table) return stitches;
  csv.close();
  if (!csv) throw InputError((out / "whiskers.csv").string() + ": cannot write");
  fs::rename(out / "whiskers.csv.tmp", out / "whiskers.csv");
  if (writer) writer->finish();
  return stitches;
}

}  // namespace sinew::tools
