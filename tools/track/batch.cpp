#include "tools/track/batch.hpp"

#include <fcntl.h>
#include <fmt/core.h>
#include <fnmatch.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <sstream>

#include "rt/whisker/detection.hpp"
#include "rt/whisker/readout.hpp"
#include "rt/whisker/session.hpp"
#include "tools/batch/child_processes.hpp"
#include "tools/batch/manifest_paths.hpp"
#include "tools/io/csv_fields.hpp"
#include "tools/io/json_file.hpp"
#include "tools/track/whisker_chunks.hpp"

namespace sinew::tools {
namespace {

namespace fs = std::filesystem;

const std::vector<std::string> kOptionKeys = {
    "face",           "min_length_px",     "redetect",       "first",         "count",
    "stride",         "rest_frame",        "rest_frames",    "repair_traces", "mm_per_px",
    "whisker_preset", "young_modulus_gpa", "base_radius_um", "tip_radius_um", "whisker_length_mm",
    "axis_angle_deg", "overlay",           "plots",          "chunks"};

// What a level of options ("options", a video) sets beyond WhiskerTrackArgs: the optional outputs.
struct ExtraOutputs {
  bool overlay = false, plots = false;
  int chunks = 1;
};

int non_negative_int(const JsonCursor& c) {
  const long v = c.integer();
  if (v < 0 || v > 1'000'000'000) c.fail("must be a non-negative integer");
  return static_cast<int>(v);
}

// One level of options onto the run's arguments: the preset first, then single values over it.
// `keys`: the keys allowed beside the options (a video's "video" and "out").
void apply_options(const JsonCursor& o, WhiskerTrackArgs& a, ExtraOutputs& extra,
                   const std::vector<std::string>& keys = {}) {
  if (!o.value().is_object()) o.fail("must be an object of options");
  std::vector<std::string> allowed = kOptionKeys;
  allowed.insert(allowed.end(), keys.begin(), keys.end());
  o.expect_keys(allowed);
  rt::WhiskerPhysics& physics = a.readout.physics;
  if (o.has("whisker_preset")) {
    const std::string name = o.at("whisker_preset").string();
    const auto preset = rt::whisker_preset(name);
    if (!preset) {
      std::string known;
      for (const auto& n : rt::whisker_preset_names()) known += (known.empty() ? "" : ", ") + n;
      o.at("whisker_preset").fail("= \"" + name + "\" is not a preset (known: " + known + ")");
    }
    const double mm_per_px = physics.mm_per_px;
    physics = *preset;
    physics.mm_per_px = mm_per_px;
  }
  if (o.has("face")) {
    a.face = o.at("face").string();
    if (!rt::face_side_from_string(a.face)) {
      o.at("face").fail("= \"" + a.face + "\" must be auto, left, right, top or bottom");
    }
  }
  if (o.has("redetect")) {
    a.redetect = o.at("redetect").string();
    if (!rt::redetect_from_string(a.redetect)) {
      o.at("redetect").fail("= \"" + a.redetect + "\" must be every, lost or never");
    }
  }
  if (o.has("min_length_px")) a.min_length_px = o.at("min_length_px").finite_number();
  if (o.has("first")) a.first = non_negative_int(o.at("first"));
  if (o.has("count")) a.count = non_negative_int(o.at("count"));
  if (o.has("stride")) {
    a.stride = non_negative_int(o.at("stride"));
    if (a.stride < 1) o.at("stride").fail("must be at least 1");
  }
  if (o.has("rest_frame")) a.rest_frame = non_negative_int(o.at("rest_frame"));
  if (o.has("rest_frames")) {
    a.rest_frames = non_negative_int(o.at("rest_frames"));
    if (a.rest_frames < 1) o.at("rest_frames").fail("must be at least 1");
  }
  if (o.has("repair_traces")) a.repair_traces = o.at("repair_traces").boolean();
  if (o.has("mm_per_px")) physics.mm_per_px = o.at("mm_per_px").finite_number();
  if (o.has("young_modulus_gpa"))
    physics.young_modulus_gpa = o.at("young_modulus_gpa").positive_number();
  if (o.has("base_radius_um")) physics.base_radius_um = o.at("base_radius_um").finite_number();
  if (o.has("tip_radius_um")) physics.tip_radius_um = o.at("tip_radius_um").finite_number();
  if (o.has("whisker_length_mm")) physics.length_mm = o.at("whisker_length_mm").finite_number();
  if (o.has("axis_angle_deg")) a.readout.axis_angle_deg = o.at("axis_angle_deg").finite_number();
  if (o.has("overlay")) extra.overlay = o.at("overlay").boolean();
  if (o.has("plots")) extra.plots = o.at("plots").boolean();
  if (o.has("chunks")) {
    extra.chunks = non_negative_int(o.at("chunks"));
    if (extra.chunks < 1) o.at("chunks").fail("must be at least 1");
  }
  if (extra.chunks > 1 && (extra.overlay || extra.plots || a.stride != 1)) {
    o.fail(
        "a video tracked in chunks has no overlay or plots and a stride of 1 (its chunks' "
        "results are stitched; track it in one piece for those)");
  }
  if (const auto error = a.readout.validate()) o.fail(*error);
}

// The results folder's files, all of which a fresh run of the video replaces.
struct VideoFiles {
  fs::path dir;
  fs::path results() const { return dir / "results.jsonl"; }
  fs::path table() const { return dir / "whiskers.csv"; }
  fs::path hdf5() const { return dir / "whiskers.h5"; }
  fs::path log() const { return dir / "log.txt"; }
  fs::path done() const { return dir / "done.json"; }
  fs::path failed() const { return dir / "failed.json"; }
  fs::path overlay() const { return dir / "overlay.mp4"; }
  fs::path plots() const { return dir / "plots"; }
};

void finish_args(TrackBatchVideo& v, const ExtraOutputs& extra) {
  const VideoFiles f{v.out_dir};
  v.args.input = v.video;
  v.args.out = f.results().string();
  v.args.csv = f.table().string();
  v.args.hdf5 = f.hdf5().string();
  v.args.overlay = extra.overlay ? f.overlay().string() : "";
  v.args.plots = extra.plots ? f.plots().string() : "";
  v.args.quiet = false;  // its own summary goes to its log.txt
  v.chunks = extra.chunks;
}

// Writes text to `path` atomically: a reader sees the old file or the whole new one, never half.
void write_atomically(const fs::path& path, const std::string& text) {
  const fs::path tmp = path.string() + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    if (!out) throw InputError(tmp.string() + ": cannot open file for writing");
    out << text;
    out.flush();
    if (!out) throw InputError(tmp.string() + ": cannot write");
  }
  // The data on disk before the rename, so that a crash cannot leave a named but empty marker.
  if (const int fd = ::open(tmp.c_str(), O_RDONLY); fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) throw InputError(path.string() + ": cannot rename " + tmp.string() + ": " + ec.message());
}

// The summary row's figures from the video's table (one row per whisker per frame).
void figures_from_table(const fs::path& table, TrackBatchRow& row) {
  std::ifstream in(table);
  if (!in) throw InputError(table.string() + ": cannot open the table just written");
  std::string line;
  std::getline(in, line);
  const std::vector<std::string> header = split_csv_fields(line);
  const auto contact_col = std::find(header.begin(), header.end(), "contact") - header.begin();
  std::set<long> frames, contact_frames;
  int max_id = -1;
  long rows = 0, lost = 0;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = split_csv_fields(line);
    if (f.size() < 3) continue;
    const long frame = std::strtol(f[0].c_str(), nullptr, 10);
    frames.insert(frame);
    max_id = std::max(max_id, static_cast<int>(std::strtol(f[1].c_str(), nullptr, 10)));
    ++rows;
    lost += f[2] == "lost";
    if (contact_col < static_cast<long>(f.size()) && f[contact_col] == "1") {
      contact_frames.insert(frame);
    }
  }
  row.frames = static_cast<int>(frames.size());
  row.whiskers = max_id + 1;
  row.contact_frames = static_cast<int>(contact_frames.size());
  row.lost_fraction = rows > 0 ? static_cast<double>(lost) / rows : 0.0;
}

nlohmann::json row_json(const TrackBatchRow& r) {
  return {{"video", r.video},
          {"frames", r.frames},
          {"whiskers", r.whiskers},
          {"lost_fraction", r.lost_fraction},
          {"contact_frames", r.contact_frames},
          {"wall_seconds", r.wall_seconds}};
}

// A marker file's row; std::nullopt when it is absent or unreadable (then the video runs again).
std::optional<TrackBatchRow> read_done(const TrackBatchVideo& v) {
  const VideoFiles f{v.out_dir};
  std::ifstream in(f.done());
  if (!in) return std::nullopt;
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    TrackBatchRow r;
    r.video = v.video;
    r.out_dir = v.out_dir;
    r.frames = j.at("frames").get<int>();
    r.whiskers = j.at("whiskers").get<int>();
    r.lost_fraction = j.at("lost_fraction").get<double>();
    r.contact_frames = j.at("contact_frames").get<int>();
    r.wall_seconds = j.at("wall_seconds").get<double>();
    r.status = "done earlier";
    return r;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

std::string read_failure(const TrackBatchVideo& v) {
  const VideoFiles f{v.out_dir};
  std::ifstream in(f.failed());
  if (in) {
    try {
      return nlohmann::json::parse(in).at("reason").get<std::string>();
    } catch (const std::exception&) {
    }
  }
  return "";
}

// The child: a clean folder, its output into log.txt, the run, the summary row, then done.json.
int track_one(const TrackBatchVideo& v) {
  const VideoFiles f{v.out_dir};
  fs::create_directories(f.dir);
  for (const fs::path& p : {f.done(), f.failed(), f.results(), f.table(), f.hdf5(), f.overlay()}) {
    fs::remove(p);
    fs::remove(p.string() + ".tmp");
  }
  fs::remove_all(f.plots());
  std::fflush(nullptr);
  const int log = ::open(f.log().c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (log < 0) throw InputError(f.log().string() + ": cannot open for writing");
  ::dup2(log, STDOUT_FILENO);
  ::dup2(log, STDERR_FILENO);
  ::close(log);
  const auto start = std::chrono::steady_clock::now();
  try {
    run_whiskers(v.args);
    TrackBatchRow row;
    row.video = v.video;
    row.wall_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    figures_from_table(f.table(), row);
    write_atomically(f.done(), row_json(row).dump(2) + "\n");
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "sinew-track: " << e.what() << "\n";
    std::cerr.flush();
    std::string reason = e.what();
    // The run names its input first ("a.mp4: cannot open ..."); the batch line names it anyway.
    if (reason.rfind(v.video + ": ", 0) == 0) reason = reason.substr(v.video.size() + 2);
    write_atomically(f.failed(),
                     nlohmann::json{{"video", v.video}, {"reason", reason}}.dump() + "\n");
    return 2;
  }
}

std::string format_duration(double s) {
  if (s < 60) return fmt::format("{:.0f} s", s);
  if (s < 3600)
    return fmt::format("{} min {:02.0f} s", static_cast<int>(s / 60), std::fmod(s, 60.0));
  return fmt::format("{} h {:02d} min", static_cast<int>(s / 3600),
                     static_cast<int>(std::fmod(s, 3600.0) / 60));
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string summary_csv(const std::vector<TrackBatchRow>& rows) {
  std::string s = "video,out,frames,whiskers,lost_fraction,contact_frames,wall_seconds,status\n";
  for (const TrackBatchRow& r : rows) {
    s += fmt::format("{},{},{},{},{:.6f},{},{:.3f},{}\n", csv_field(r.video), csv_field(r.out_dir),
                     r.frames, r.whiskers, r.lost_fraction, r.contact_frames, r.wall_seconds,
                     csv_field(r.status));
  }
  return s;
}

void print_table(const std::vector<TrackBatchRow>& rows) {
  std::size_t width = 5;
  for (const TrackBatchRow& r : rows) width = std::max(width, r.video.size());
  width = std::min<std::size_t>(width, 60);
  fmt::print("{:<{}}  {:>7}  {:>8}  {:>6}  {:>14}  {:>8}  {}\n", "video", width, "frames",
             "whiskers", "lost", "contact frames", "wall s", "status");
  for (const TrackBatchRow& r : rows) {
    fmt::print("{:<{}}  {:>7}  {:>8}  {:>6.3f}  {:>14}  {:>8.1f}  {}\n", r.video, width, r.frames,
               r.whiskers, r.lost_fraction, r.contact_frames, r.wall_seconds, r.status);
  }
}

// A job of the batch: a whole video, or one chunk of a video tracked in chunks.
struct BatchUnit {
  std::size_t video = 0;
  int chunk = -1;       // -1: the whole video
  TrackBatchVideo job;  // what the child tracks (a chunk: its frames into its own folder)
};

// A chunked video's chunks over its frames (--first/--count respected).
std::vector<WhiskerChunk> chunk_plan(const TrackBatchVideo& v) {
  const int frames = v.args.count >= 0 ? v.args.count : count_input_frames(v.video) - v.args.first;
  if (frames <= 0) throw InputError("no frame to track from frame " + std::to_string(v.args.first));
  std::vector<WhiskerChunk> plan = plan_whisker_chunks(v.args.first, frames, v.chunks);
  if (v.args.count >= 0) plan.back().count = v.args.first + v.args.count - plan.back().first;
  return plan;
}

TrackBatchVideo chunk_job(const TrackBatchVideo& v, const WhiskerChunk& k, int c) {
  TrackBatchVideo job = v;
  job.out_dir = (fs::path(v.out_dir) / ("chunk_" + std::to_string(c))).string();
  finish_args(job, ExtraOutputs{});
  job.args.first = k.first;
  job.args.count = k.count;
  if (k.first < k.output_from) {
    // The rest shape within the overlap's first half, so that the overlap's second half measures
    // the chunk's rest against the stitched one (whisker_chunks.hpp).
    const int half = (k.output_from - k.first) / 2;
    job.args.rest_frame = 0;
    job.args.rest_frames = std::min(job.args.rest_frames, half);
  }
  return job;
}

// Every chunk done: their results stitched into the video's folder, then its done.json. The wall
// time is the chunks' sum (the work; they ran side by side).
void finish_chunked(const TrackBatchVideo& v, const std::vector<WhiskerChunk>& plan,
                    TrackBatchRow& row) {
  std::vector<std::string> dirs;
  double seconds = 0.0;
  for (std::size_t c = 0; c < plan.size(); ++c) {
    const TrackBatchVideo job = chunk_job(v, plan[c], static_cast<int>(c));
    const auto done = read_done(job);
    if (!done) throw InputError(job.out_dir + ": the chunk has no done.json");
    seconds += done->wall_seconds;
    dirs.push_back(job.out_dir);
  }
  const VideoFiles f{v.out_dir};
  stitch_whisker_chunks(dirs, plan, f.dir.string(), true, true);
  row.video = v.video;
  row.out_dir = v.out_dir;
  row.wall_seconds = seconds;
  figures_from_table(f.table(), row);
  fs::remove(f.failed());
  write_atomically(f.done(), row_json(row).dump(2) + "\n");
  row.status = "tracked";
}

}  // namespace

TrackBatchManifest read_track_batch_manifest(const std::string& path) {
  return parse_json_file(
      path, [&](const nlohmann::json& doc) { return parse_track_batch_manifest(doc, path); });
}

TrackBatchManifest parse_track_batch_manifest(const nlohmann::json& doc, const std::string& path) {
  const JsonCursor root(doc, path);
  if (!doc.is_object()) root.fail("must be an object with \"videos\" and/or \"folder\"");
  root.expect_keys({"out", "options", "videos", "folder", "glob"});
  TrackBatchManifest m;
  m.path = path;
  m.out_dir = root.has("out")
                  ? resolve_manifest_path(path, root.at("out"))
                  : resolve_manifest_path(path, fs::path(path).stem().string() + "_results");
  WhiskerTrackArgs base;
  ExtraOutputs base_extra;
  if (root.has("options")) apply_options(root.at("options"), base, base_extra);

  std::map<std::string, std::string> out_dirs;  // normalised folder → the video using it
  auto add = [&](const std::string& video, const std::string& out_name, const JsonCursor* entry,
                 const JsonCursor& where) {
    TrackBatchVideo v;
    v.video = video;
    v.args = base;
    ExtraOutputs extra = base_extra;
    if (entry != nullptr) apply_options(*entry, v.args, extra, {"video", "out"});
    v.out_dir = (fs::path(m.out_dir) / out_name).lexically_normal().string();
    const std::string key = fs::weakly_canonical(fs::absolute(v.out_dir)).string();
    const auto [it, inserted] = out_dirs.emplace(key, video);
    if (!inserted) {
      where.fail("the results folder \"" + v.out_dir + "\" of " + video + " is also " + it->second +
                 "'s (give one an \"out\")");
    }
    finish_args(v, extra);
    m.videos.push_back(std::move(v));
  };

  if (root.has("videos")) {
    const JsonCursor videos = root.at("videos");
    for (std::size_t i = 0; i < videos.array_size(); ++i) {
      const JsonCursor e = videos.at(i);
      if (!e.value().is_object()) e.fail("must be {\"video\": FILE, ...options}");
      const std::string video = resolve_manifest_path(path, e.at("video"));
      const std::string out = e.has("out") ? e.at("out").string() : fs::path(video).stem().string();
      if (out.empty()) e.at("out").fail("must name a folder (it is empty)");
      add(video, out, &e, e);
    }
  }
  if (root.has("folder") != root.has("glob")) {
    root.fail("\"folder\" and \"glob\" go together (every file of the folder matching the glob)");
  }
  if (root.has("folder")) {
    const std::string folder = resolve_manifest_path(path, root.at("folder"));
    const std::string glob = root.at("glob").string();
    std::error_code ec;
    std::vector<std::string> found;
    for (const auto& entry : fs::directory_iterator(folder, ec)) {
      if (!entry.is_regular_file()) continue;
      const std::string name = entry.path().filename().string();
      if (fnmatch(glob.c_str(), name.c_str(), 0) == 0) found.push_back(entry.path().string());
    }
    if (ec) root.at("folder").fail("= \"" + folder + "\" cannot be read: " + ec.message());
    if (found.empty()) root.at("glob").fail("= \"" + glob + "\" matches no file in " + folder);
    std::sort(found.begin(), found.end());
    for (const std::string& video : found)
      add(video, fs::path(video).stem().string(), nullptr, root.at("glob"));
  }
  if (m.videos.empty()) root.fail("names no video (give \"videos\" or \"folder\" and \"glob\")");
  return m;
}

int run_track_batch(const TrackBatchManifest& manifest, const TrackBatchOptions& options,
                    std::vector<TrackBatchRow>* rows_out) {
  const std::size_t n = manifest.videos.size();
  std::vector<TrackBatchRow> rows(n);
  std::vector<BatchUnit> units;                     // the jobs: whole videos and chunks
  std::vector<std::vector<WhiskerChunk>> plans(n);  // a chunked video's chunks
  std::vector<int> chunks_left(n, 0);
  std::vector<std::size_t> selected;
  if (options.task) {
    selected.push_back(*options.task);
  } else {
    for (std::size_t i = 0; i < n; ++i) selected.push_back(i);
  }
  std::size_t skipped = 0, videos_to_run = 0;
  auto fail = [&](std::size_t i, const std::string& reason) {
    rows[i].status = "failed: " + reason;
    const TrackBatchVideo& v = manifest.videos[i];
    if (v.chunks > 1) {  // a chunk's own failed.json is in its folder; the video's for --gather
      fs::create_directories(v.out_dir);
      write_atomically(VideoFiles{v.out_dir}.failed(),
                       nlohmann::json{{"video", v.video}, {"reason", reason}}.dump() + "\n");
    }
    // The one line for a bad video: the file and the reason.
    fmt::print(stderr, "sinew-track: {}: {}\n", manifest.videos[i].video, reason);
  };
  auto stitch = [&](std::size_t i) {
    try {
      finish_chunked(manifest.videos[i], plans[i], rows[i]);
    } catch (const std::exception& e) {
      fail(i, std::string("stitching its chunks: ") + e.what());
    }
  };
  for (const std::size_t i : selected) {
    const TrackBatchVideo& v = manifest.videos[i];
    rows[i].video = v.video;
    rows[i].out_dir = v.out_dir;
    if (auto done = read_done(v)) {
      rows[i] = *done;
      ++skipped;
    } else if (options.gather) {
      const std::string reason = read_failure(v);
      rows[i].status = reason.empty() ? "not run" : "failed: " + reason;
    } else if (v.chunks <= 1) {
      units.push_back({i, -1, v});
      ++videos_to_run;
    } else {
      try {
        plans[i] = chunk_plan(v);
      } catch (const std::exception& e) {
        fail(i, e.what());
        continue;
      }
      ++videos_to_run;
      for (std::size_t c = 0; c < plans[i].size(); ++c) {
        TrackBatchVideo job = chunk_job(v, plans[i][c], static_cast<int>(c));
        if (read_done(job)) continue;  // a chunk finished by an earlier run
        units.push_back({i, static_cast<int>(c), std::move(job)});
        ++chunks_left[i];
      }
      if (chunks_left[i] == 0) stitch(i);
    }
  }
  std::vector<std::size_t> to_run(units.size());
  for (std::size_t u = 0; u < units.size(); ++u) to_run[u] = u;

  const auto start = std::chrono::steady_clock::now();
  std::size_t finished = 0;
  std::optional<int> task_status;
  if (!options.quiet && !options.gather) {
    fmt::print(stderr,
               "sinew-track --batch {}: {} video{}, {} done earlier (skipped), {} to track with {} "
               "job{}{}\n",
               manifest.path, selected.size(), selected.size() == 1 ? "" : "s", skipped,
               videos_to_run, options.jobs, options.jobs == 1 ? "" : "s",
               units.size() != videos_to_run
                   ? fmt::format(" ({} jobs with the chunks)", units.size())
                   : "");
  }
  run_in_children(
      to_run, options.jobs, "sinew-track", [&](std::size_t u) { return track_one(units[u].job); },
      nullptr,
      [&](std::size_t u, const ChildOutcome& o) {
        const BatchUnit& unit = units[u];
        const std::size_t i = unit.video;
        const TrackBatchVideo& v = manifest.videos[i];
        TrackBatchRow& row = rows[i];
        ++finished;
        if (unit.chunk < 0) task_status = o.task_status();
        const bool earlier_failure = row.status.rfind("failed", 0) == 0;
        if (o.ok() && unit.chunk < 0) {
          if (auto done = read_done(v)) row = *done;
          row.status = "tracked";
        } else if (o.ok()) {
          if (--chunks_left[i] == 0 && !earlier_failure) stitch(i);
        } else if (!earlier_failure) {
          std::string reason = describe_abnormal_end(o);
          if (reason.empty()) reason = read_failure(unit.job);
          if (reason.empty())
            reason = fmt::format("exit {} (see {})", o.exit_status,
                                 VideoFiles{unit.job.out_dir}.log().string());
          if (unit.chunk >= 0) reason = fmt::format("chunk {}: {}", unit.chunk, reason);
          fail(i, reason);
          row.wall_seconds = o.seconds;
        }
        if (!options.quiet) {
          const double elapsed =
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
          const std::size_t total = to_run.size();
          constexpr int kBar = 24;
          const int filled = static_cast<int>(kBar * finished / std::max<std::size_t>(total, 1));
          const double eta = elapsed / finished * static_cast<double>(total - finished);
          const std::string what =
              unit.chunk < 0 ? v.video : fmt::format("{} (chunk {})", v.video, unit.chunk);
          fmt::print(stderr, "[{}{}] {}/{} {:.0f} s, ETA {}: {} {}\n", std::string(filled, '#'),
                     std::string(kBar - filled, '.'), finished, total, elapsed,
                     finished == total ? "done" : format_duration(eta), what,
                     !o.ok()          ? "failed"
                     : unit.chunk < 0 ? fmt::format("({} frames, {} whiskers, {:.1f} s)",
                                                    row.frames, row.whiskers, row.wall_seconds)
                                      : fmt::format("({:.1f} s)", o.seconds));
        }
      });

  std::vector<TrackBatchRow> selected_rows;
  for (const std::size_t i : selected) selected_rows.push_back(rows[i]);
  std::size_t bad = 0;
  for (const TrackBatchRow& r : selected_rows) bad += !r.ok();
  if (!options.task) {
    fs::create_directories(manifest.out_dir);
    write_atomically(fs::path(manifest.out_dir) / "summary.csv", summary_csv(selected_rows));
  }
  if (!options.quiet) {
    print_table(selected_rows);
    fmt::print(
        "batch {}: {} of {} video{} tracked ({} done earlier), {} failed{}\n", manifest.path,
        selected.size() - bad, selected.size(), selected.size() == 1 ? "" : "s", skipped, bad,
        options.task ? "" : "; summary: " + (fs::path(manifest.out_dir) / "summary.csv").string());
    std::fflush(stdout);
  }
  if (rows_out != nullptr) *rows_out = selected_rows;
  if (options.task) {
    if (task_status) return *task_status;
    return selected_rows.front().ok() ? 0 : 1;
  }
  return bad == 0 ? 0 : 1;
}

}  // namespace sinew::tools
