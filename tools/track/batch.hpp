#pragma once
/// sinew-track --batch: many whisker videos from one manifest (docs/whisker_batch.md), each in a
/// child process of its own (tools/batch/child_processes.hpp), several at once with --jobs, into
/// one results folder per video, with a summary table; resumable and a Slurm job array's task.
///
/// Manifest (keys other than these are errors; paths relative to the manifest's folder):
/// {
///   "out": "results",                       // root of the results (default: <manifest>_results)
///   "options": {"face": "left", ...},       // for every video (keys as a video's, below)
///   "videos": [{"video": "a.mp4", "out": "a", "face": "right", "mm_per_px": 0.05}],
///   "folder": "videos", "glob": "*.mp4"     // and/or every file of a folder matching the glob
/// }
/// A video's "out" (default: its file name without the extension) is relative to the root; no two
/// videos may share one. Options: face, min_length_px, redetect, first, count, stride, rest_frame,
/// rest_frames, repair_traces, mm_per_px, whisker_preset, young_modulus_gpa, base_radius_um,
/// tip_radius_um, whisker_length_mm, axis_angle_deg, overlay (true: overlay.mp4), plots (true:
/// plots/), chunks (N > 1: the video is cut into N chunks tracked as separate jobs, each into
/// chunk_<k>/, and their results stitched; no overlay, plots or stride then).
///
/// Each video's folder gets results.jsonl, whiskers.csv, whiskers.h5 and log.txt (the run's own
/// output) and, last, done.json (its summary row, written atomically): a video with done.json is
/// skipped by a later run; one without it (killed halfway, or failed) is tracked again from the
/// start. A failed video gets failed.json with the reason instead.
///
/// Exit status: 0 every selected video tracked (now or before); 1 at least one failed (one line on
/// stderr each, naming the file and the reason); 2 bad manifest or usage. With a task selected
/// (--task N or SLURM_ARRAY_TASK_ID), the status is that video's own (2 bad video, 1 a signal).

#include <cstddef>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "tools/track/whiskers.hpp"

namespace sinew::tools {

/// One video of a manifest: its input, its results folder and the run's arguments (outputs set).
struct TrackBatchVideo {
  std::string video;    ///< resolved path (file, image or printf pattern)
  std::string out_dir;  ///< resolved results folder
  WhiskerTrackArgs args;
  int chunks = 1;  ///< > 1: tracked as this many chunks at once, stitched (whisker_chunks.hpp)
};

struct TrackBatchManifest {
  std::string path;
  std::string out_dir;                  ///< root of the results; summary.csv goes here
  std::vector<TrackBatchVideo> videos;  ///< at least one, in manifest order (glob: sorted)
};

/// Reads and validates a manifest (throws InputError naming the file, line, column and field).
TrackBatchManifest read_track_batch_manifest(const std::string& path);
/// The same for a parsed document; `path` names it and resolves relative names.
TrackBatchManifest parse_track_batch_manifest(const nlohmann::json& doc, const std::string& path);

/// One row of the summary table.
struct TrackBatchRow {
  std::string video, out_dir;
  int frames = 0, whiskers = 0, contact_frames = 0;
  double lost_fraction = 0.0;  ///< lost whisker-frames / whisker-frames
  double wall_seconds = 0.0;   ///< the video's own run (an earlier run's when skipped)
  std::string status;          ///< "tracked", "done earlier", "failed: <reason>", "not run"
  bool ok() const { return status == "tracked" || status == "done earlier"; }
};

struct TrackBatchOptions {
  int jobs = 1;                     ///< videos tracked at once (processes)
  std::optional<std::size_t> task;  ///< one video alone (a Slurm array task)
  bool gather = false;  ///< track nothing: the summary from the videos' done/failed files
  bool quiet = false;   ///< no progress, no printed table (errors still)
};

/// Runs the batch (or gathers it), writes <root>/summary.csv unless a task is selected, fills
/// `rows` (may be null) in manifest order and returns the exit status above.
int run_track_batch(const TrackBatchManifest& manifest, const TrackBatchOptions& options,
                    std::vector<TrackBatchRow>* rows = nullptr);

}  // namespace sinew::tools
