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

// One chunk's results: the detection line and the frame lines by frame index.
struct ChunkResults {
  nlohmann::json detection;
  std::map<int, nlohmann::json> frames;
};

ChunkResults read_chunk(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file.string() + ": cannot open a chunk's results");
  ChunkResults r;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty()) continue;
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(line);
    } catch (const std::exception& e) {
      throw InputError(file.string() + ":" + std::to_string(number) + ": not JSON: " + e.what());
    }
    if (j.contains("detection")) {
      r.detection = std::move(j);
    } else if (j.contains("frame") && j.contains("whiskers")) {
      const int frame = j.at("frame").get<int>();  // before j is moved into the map
      r.frames[frame] = std::move(j);
    } else {
      throw InputError(file.string() + ":" + std::to_string(number) +
                       ": neither a detection nor a frame line");
    }
  }
  if (r.detection.is_null()) throw InputError(file.string() + ": no detection line");
  return r;
}

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

// Stitched ids for chunk c's whiskers from the stitched frames over the overlap's second half.
// A follicle's position along the face edge: y for a face on the left or right, else x.
double along_face(const nlohmann::json& whisker, bool vertical_edge) {
  return whisker.at("follicle")[vertical_edge ? 1 : 0].get<double>();
}

// Whiskers of the chunk that no stitched whisker's curve matched over the overlap (the stitched
// one was not tracked there: a chunk before this one did not find it): by follicle order along the
// face, which whiskers keep. A chunk whisker whose nearest matched neighbours on either side along
// the face enclose exactly one free stitched id (at its last tracked frame) takes that id.
void match_by_order(const std::map<int, nlohmann::json>& stitched, const ChunkResults& chunk,
                    const WhiskerChunk& plan, bool vertical_edge, ChunkStitch& m,
                    std::vector<bool>& taken) {
  std::map<int, double> last;  // stitched id → its follicle along the face when last tracked
  for (auto it = stitched.begin(); it != stitched.end() && it->first < plan.output_from; ++it) {
    for (const auto& w : it->second.at("whiskers")) {
      if (tracked(w)) last[w.at("id").get<int>()] = along_face(w, vertical_edge);
    }
  }
  const auto line = chunk.frames.lower_bound(plan.output_from);
  if (line == chunk.frames.begin()) return;
  std::vector<std::pair<double, int>>
      order;  // (along the face, chunk id) on its last overlap frame
  for (const auto& w : std::prev(line)->second.at("whiskers")) {
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
        lo = last[p];
        break;
      }
    }
    for (std::size_t j = k + 1; j < order.size(); ++j) {
      const int p = m.stitched_id[order[j].second];
      if (p >= 0 && last.count(p)) {
        hi = last[p];
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

ChunkStitch match_ids(const std::map<int, nlohmann::json>& stitched, const ChunkResults& chunk,
                      const WhiskerChunk& plan, bool vertical_edge, int& next_id) {
  const int from = plan.first + (plan.output_from - plan.first) / 2;
  std::map<std::pair<int, int>, std::pair<double, int>> sums;  // (chunk id, stitched id)
  int chunk_ids = 0;
  for (const auto& [frame, line] : chunk.frames) {
    for (const auto& w : line.at("whiskers"))
      chunk_ids = std::max(chunk_ids, w.at("id").get<int>() + 1);
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
  match_by_order(stitched, chunk, plan, vertical_edge, m, taken);
  for (int& id : m.stitched_id) {
    if (id < 0) id = next_id++;
  }
  return m;
}

bool is_rest_relative(const std::string& key) {
  return key.rfind("delta_curvature", 0) == 0 ||
         (key.rfind("m0_", 0) == 0 && key.find("_sd") == std::string::npos);
}

// Per stitched id and rest-relative key, the mean of (stitched − chunk) over the overlap frames
// where both have it: the two rest shapes' difference, added to the chunk's values.
std::map<std::pair<int, std::string>, double> rest_offsets(
    const std::map<int, nlohmann::json>& stitched, const ChunkResults& chunk,
    const WhiskerChunk& plan, const ChunkStitch& ids) {
  std::map<std::pair<int, std::string>, std::pair<double, int>> sums;
  const int from = plan.first + (plan.output_from - plan.first) / 2;
  for (const auto& [frame, line] : chunk.frames) {
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
  std::map<std::pair<int, std::string>, double> offsets;
  for (const auto& [k, acc] : sums) offsets[k] = acc.first / acc.second;
  return offsets;
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
  std::map<int, nlohmann::json> stitched;  // frame → line, stitched ids
  std::vector<ChunkStitch> stitches;
  nlohmann::json detection;
  int next_id = 0;
  // Per chunk, the rest offsets (stitched id, key) and the id mapping, for the table too.
  std::vector<std::map<std::pair<int, std::string>, double>> offsets(chunk_dirs.size());
  for (std::size_t c = 0; c < chunk_dirs.size(); ++c) {
    const ChunkResults r = read_chunk(fs::path(chunk_dirs[c]) / "results.jsonl");
    ChunkStitch ids;
    if (c == 0) {
      detection = r.detection;
      for (const auto& w : detection.at("detection").at("whiskers")) {
        next_id = std::max(next_id, w.at("id").get<int>() + 1);
      }
      for (const auto& [frame, line] : r.frames) {
        for (const auto& w : line.at("whiskers"))
          next_id = std::max(next_id, w.at("id").get<int>() + 1);
      }
      ids.stitched_id.resize(static_cast<std::size_t>(next_id));
      for (int i = 0; i < next_id; ++i) ids.stitched_id[i] = i;
      ids.distance_px.assign(static_cast<std::size_t>(next_id), 0.0);
    } else {
      const nlohmann::json& face_field = detection.at("detection").at("face");
      const bool vertical = !face_field.is_string() ||
                            face_field.get_ref<const std::string&>() == "left" ||
                            face_field.get_ref<const std::string&>() == "right";
      ids = match_ids(stitched, r, chunks[c], vertical, next_id);
      offsets[c] = rest_offsets(stitched, r, chunks[c], ids);
    }
    for (const auto& [frame, line] : r.frames) {
      if (frame < chunks[c].output_from) continue;
      nlohmann::json l = line;
      for (auto& w : l.at("whiskers")) {
        const int id = ids.stitched_id.at(w.at("id").get<int>());
        w["id"] = id;
        for (auto& [key, value] : w.items()) {
          const auto o = offsets[c].find({id, key});
          if (o != offsets[c].end() && value.is_number()) value = value.get<double>() + o->second;
        }
      }
      stitched[frame] = std::move(l);
    }
    stitches.push_back(std::move(ids));
  }

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
  {
    std::ofstream o(out / "results.jsonl.tmp", std::ios::trunc);
    o << detection.dump() << "\n";
    for (const auto& [frame, line] : stitched) o << line.dump() << "\n";
    if (!o) throw InputError((out / "results.jsonl").string() + ": cannot write");
  }
  fs::rename(out / "results.jsonl.tmp", out / "results.jsonl");
  if (!table) return stitches;

  // The table: each chunk's rows from its output_from on, ids and rest-relative columns mapped.
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  for (std::size_t c = 0; c < chunk_dirs.size(); ++c) {
    const fs::path file = fs::path(chunk_dirs[c]) / "whiskers.csv";
    std::ifstream in(file);
    if (!in) throw InputError(file.string() + ": cannot open a chunk's table");
    std::string line;
    std::getline(in, line);
    if (c == 0) header = split_csv_fields(line);
    while (std::getline(in, line)) {
      std::vector<std::string> f = split_csv_fields(line);
      if (f.size() < 3) continue;
      if (std::stoi(f[0]) < chunks[c].output_from) continue;
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
  }
  std::stable_sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) {
    const int fa = std::stoi(a[0]), fb = std::stoi(b[0]);
    return fa != fb ? fa < fb : std::stoi(a[1]) < std::stoi(b[1]);
  });
  {
    std::ofstream o(out / "whiskers.csv.tmp", std::ios::trunc);
    for (std::size_t k = 0; k < header.size(); ++k) o << (k ? "," : "") << header[k];
    o << "\n";
    for (const auto& f : rows) {
      for (std::size_t k = 0; k < f.size(); ++k) o << (k ? "," : "") << f[k];
      o << "\n";
    }
    if (!o) throw InputError((out / "whiskers.csv").string() + ": cannot write");
  }
  fs::rename(out / "whiskers.csv.tmp", out / "whiskers.csv");
  if (!hdf5) return stitches;

  // The HDF5 file from the stitched table and centrelines; a whisker's centreline rows have its
  // largest node count over the chunks (a chunk's detection may give it fewer nodes), NaN-padded.
  std::map<int, int> nodes;
  for (const auto& [frame, line] : stitched) {
    for (const auto& w : line.at("whiskers")) {
      int& n = nodes[w.at("id").get<int>()];
      n = std::max(n, static_cast<int>(w.at("nodes").size()));
    }
  }
  std::vector<int> node_counts(static_cast<std::size_t>(next_id), 1);
  for (const auto& [id, n] : nodes) node_counts[id] = std::max(1, n);
  std::string source, units, readout;
  {
    const std::string first = (fs::path(chunk_dirs[0]) / "whiskers.h5").string();
    const hid_t f = H5Fopen(first.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0) throw InputError(first + ": cannot open a chunk's HDF5 file");
    source = read_attribute(f, "source");
    units = read_attribute(f, "units");
    readout = read_attribute(f, "readout");
    H5Fclose(f);
  }
  const std::vector<std::string> value_columns(header.begin() + 3, header.end());
  WhiskerHdf5Writer writer((out / "whiskers.h5").string(), value_columns, node_counts);
  writer.attribute("source", source);
  writer.attribute("units", units);
  writer.attribute("readout", readout);
  writer.attribute("chunks", record.dump());
  std::vector<double> values(value_columns.size());
  for (const auto& f : rows) {
    for (std::size_t k = 0; k < values.size(); ++k) {
      values[k] = k + 3 < f.size() && !f[k + 3].empty() ? std::stod(f[k + 3]) : kNan;
    }
    writer.add_row(std::stoi(f[0]), std::stoi(f[1]), f[2], values);
  }
  std::vector<std::vector<double>> centrelines(static_cast<std::size_t>(next_id));
  for (const auto& [frame, line] : stitched) {
    for (int id = 0; id < next_id; ++id) centrelines[id].assign(3 * node_counts[id], kNan);
    for (const auto& w : line.at("whiskers")) {
      if (w.at("status").get<std::string>() == "lost") continue;
      std::vector<double>& c = centrelines[w.at("id").get<int>()];
      const auto& n = w.at("nodes");
      for (std::size_t i = 0; i < n.size() && 3 * i + 2 < c.size(); ++i) {
        for (int k = 0; k < 3; ++k) c[3 * i + k] = n[i][k].get<double>();
      }
    }
    writer.add_frame(frame, centrelines);
  }
  writer.finish();
  return stitches;
}

}  // namespace sinew::tools
