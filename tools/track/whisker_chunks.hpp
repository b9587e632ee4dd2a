#pragma once
/// One long whisker video tracked as chunks in parallel (sinew-track --batch, a video's "chunks"),
/// their results stitched into the files one pass writes (docs/whisker_batch.md, "Chunks").
///
/// Chunk c > 0 starts `overlap` frames before its border: those frames let its fits settle after
/// detection and are where its identities are matched to the stitched ones (the mean distance of
/// the two curves over the overlap's second half, each id to the nearest, at most kStitchGatePx);
/// they are not written. A chunk's whisker that matches none gets a new id. What the stitching
/// guarantees, measured in tests/tools/whisker_chunks_test.cpp and the docs: identities as one
/// pass wherever the one pass's ids are themselves stable across the overlap, and nodes as one
/// pass from a few frames after each border; quantities relative to the rest shape (Δκ, M0 and the
/// contact loads) are relative to each chunk's own first frame, so the stitching adds to Δκ and M0
/// the overlap's mean difference from the chunk before (their rest shapes' difference).

#include <string>
#include <vector>

namespace sinew::tools {

/// The frames a chunk tracks, [first, first + count) (count −1: to the end), and the first of them
/// it contributes to the stitched results.
struct WhiskerChunk {
  int first = 0, count = -1, output_from = 0;
};

/// Frames before a border that a chunk tracks to settle and to be matched.
constexpr int kChunkOverlapFrames = 20;
/// The largest mean distance (px) between two curves of one whisker across a border.
constexpr double kStitchGatePx = 3.0;

/// Frames in a video file, a folder of images or a printf pattern (a video's count is its
/// container's, which may be approximate: the last chunk runs to the end regardless).
int count_input_frames(const std::string& input);

/// `chunks` chunks of about equal length over `frames` frames from `first` (stride 1); fewer when
/// a chunk would be shorter than twice the overlap.
std::vector<WhiskerChunk> plan_whisker_chunks(int first, int frames, int chunks,
                                              int overlap = kChunkOverlapFrames);

/// One chunk's id mapping: stitched_id[chunk id], and the matching's mean curve distance (px,
/// NaN for a new id).
struct ChunkStitch {
  std::vector<int> stitched_id;
  std::vector<double> distance_px;
};

/// Stitches the chunks' results (chunk_dirs[c] holds results.jsonl and, when `table`, whiskers.csv)
/// into results.jsonl, whiskers.csv and whiskers.h5 in out_dir, each written to .tmp and renamed.
/// The detection line is the first chunk's, with a "chunks" record added (each chunk's frames and
/// id mapping). Throws InputError naming the file on a malformed chunk.
std::vector<ChunkStitch> stitch_whisker_chunks(const std::vector<std::string>& chunk_dirs,
                                               const std::vector<WhiskerChunk>& chunks,
                                               const std::string& out_dir, bool table, bool hdf5);

}  // namespace sinew::tools
