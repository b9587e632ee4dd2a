#include "rt/whisker/detail/chessboard_distance.hpp"

#include <algorithm>
#include <cstdint>
#include <vector>

namespace sinew::rt::detail {

void chessboard_distance(const cv::Mat& mask, cv::Mat& depth) {
  CV_Assert(mask.type() == CV_8U);
  depth.create(mask.size(), CV_8U);
  const int w = mask.cols, h = mask.rows;
  std::vector<std::uint8_t> from_row(static_cast<std::size_t>(w));
  // Two passes with the 3 x 3 neighbourhood at unit cost (exact for the chessboard metric): from
  // the top-left, each pixel from its upper-left, upper and upper-right neighbours (a whole row at
  // once) and then its left one; from the bottom-right, from the mirrored four.
  auto pass = [&](int y, int neighbour_row, bool forward) {
    const std::uint8_t* in = mask.ptr<std::uint8_t>(y);
    std::uint8_t* d = depth.ptr<std::uint8_t>(y);
    std::uint8_t* v = from_row.data();
    if (neighbour_row >= 0) {
      // One more than the least of the three neighbours in that row (saturating at 255); a plain
      // loop over the inner pixels, which the compiler vectorises.
      const std::uint8_t* n = depth.ptr<std::uint8_t>(neighbour_row);
      auto plus_one = [](std::uint8_t m) {
        return static_cast<std::uint8_t>(std::min<std::uint8_t>(m, 254) + 1);
      };
      v[0] = plus_one(std::min(n[0], n[w > 1 ? 1 : 0]));
      for (int x = 1; x + 1 < w; ++x) v[x] = plus_one(std::min(std::min(n[x - 1], n[x]), n[x + 1]));
      if (w > 1) v[w - 1] = plus_one(std::min(n[w - 2], n[w - 1]));
    } else {
      std::fill(from_row.begin(), from_row.end(), std::uint8_t{255});
    }
    int last = 255;
    if (forward) {
      for (int x = 0; x < w; ++x) {
        const int best = in[x] ? std::min<int>(std::min(last + 1, 255), v[x]) : 0;
        d[x] = static_cast<std::uint8_t>(best);
        last = best;
      }
    } else {
      for (int x = w - 1; x >= 0; --x) {
        const int best = std::min<int>(std::min<int>(std::min(last + 1, 255), v[x]), d[x]);
        d[x] = static_cast<std::uint8_t>(best);
        last = best;
      }
    }
  };
  for (int y = 0; y < h; ++y) pass(y, y - 1, true);
  for (int y = h - 1; y >= 0; --y) pass(y, y + 1 < h ? y + 1 : -1, false);
}

}  // namespace sinew::rt::detail
