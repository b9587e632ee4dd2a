// Tracker: the search along the normals (and along the tangent at free ends) for the object's
// edges or ridge, and the polarity of a new object's edges.
#include "rt/tracker.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rt/centreline.hpp"
#include "rt/detail/order_statistic.hpp"
#include "rt/detail/solver_options.hpp"

namespace sinew::rt {

EdgePolarity Tracker::measure_polarity(const ImageView& frame) const {
  double inside = 0.0, outside = 0.0;
  int count = 0;
  const double offset = options_.half_width_px + 3.0;
  for (const SearchLine& line : lines_) {
    if (line.side <= 0.0f) continue;  // one sample per position
    const CentrelinePoint p = centreline(line.element, line.xi);
    float centre, plus, minus;
    if (frame.sample(p.position.x(), p.position.y(), &centre) &&
        frame.sample(p.position.x() + offset * p.normal.x(), p.position.y() + offset * p.normal.y(),
                     &plus) &&
        frame.sample(p.position.x() - offset * p.normal.x(), p.position.y() - offset * p.normal.y(),
                     &minus)) {
      inside += centre;
      outside += 0.5 * (plus + minus);
      ++count;
    }
  }
  if (count == 0) return EdgePolarity::kAny;
  const double contrast = (outside - inside) / count;
  if (contrast > options_.min_strength) return EdgePolarity::kDarkObject;
  if (contrast < -options_.min_strength) return EdgePolarity::kBrightObject;
  return EdgePolarity::kAny;
}

Eigen::Vector2d Tracker::expected_point(const SearchLine& line, const ModelPoint& p,
                                        Eigen::Vector2d* direction) const {
  if (line.end == 0) {
    *direction = p.normal;
    return p.position + (line.side * options_.half_width_px) * p.normal;
  }
  // The normal is the tangent turned by +90°, so the tangent is (n.y, −n.x).
  *direction = line.end * Eigen::Vector2d(p.normal.y(), -p.normal.x());
  return p.position + options_.half_width_px * *direction;
}

void Tracker::search(const ImageView& frame, int range_px) {
  const int K = options_.max_candidates;
  // With the Jacobians' parts (a few products per point): the Newton step that follows at this
  // state re-uses the points instead of evaluating its elements' rotations again.
  evaluate_points(/*normals=*/true, /*jacobians=*/true);
  ProfileSearch base = profile_search_;
  base.range_px = std::min(range_px, profile_search_.range_px);  // never past the scratch
  // In edge mode the wide first search only has to bring the model near the object's strong
  // boundaries: one pixel row is enough (a third of the samples); the band averaging that fixes
  // the final positions comes after. Thin lines in noise need the band from the start.
  if (range_px > options_.search_range_px && options_.observation == ObservationMode::kEdge) {
    base.band_px = 0;
  }
  const int margin = base.margin();
  // The whole-pixel offset of a line's centre from its sample point (± the rounded half width).
  const int half_width = static_cast<int>(std::lround(options_.half_width_px));
  auto side_offset_px = [&](const SearchLine& line) {
    return line.side > 0.0f ? half_width : line.side < 0.0f ? -half_width : 0;
  };
  float* profile = scratch_.data();
  float* response = scratch_.data() + scratch_.size() / 2;
  // Expected intensity step along the search direction (edge mode): a dark object's +n boundary
  // goes dark → bright, its −n boundary bright → dark.
  auto edge_sign = [&](const SearchLine& line) {
    if (options_.observation != ObservationMode::kEdge) return 0;
    const int sign = line.side > 0 ? 1 : -1;
    return polarity_ == EdgePolarity::kDarkObject     ? sign
           : polarity_ == EdgePolarity::kBrightObject ? -sign
                                                      : 0;
  };
  if (options_.observation == ObservationMode::kEdgeMap) {
    // The seed's observations: the edge pixels nearest the model along each line.
    for (std::size_t j = 0; j < lines_.size(); ++j) {
      SearchLine& line = lines_[j];
      line.centre = expected_point(line, points_[line.point], &line.normal);
      line.num_candidates =
          search_edge_map(frame, line.centre, line.normal, base.range_px, K, &candidates_[j * K]);
    }
    return;
  }
  // Pixels reach the cache a few sample points ahead of their sampling (see prefetch_profile).
  const int reach = (sides_ == 2 ? half_width : 0) + base.range_px + margin;
  constexpr int kPrefetchAhead = 4;
  auto prefetch = [&](std::size_t point) {
    if (point < points_.size()) {
      prefetch_profile(frame, points_[point].position, points_[point].normal, -reach,
                       2 * reach + 2);
    }
  };
  for (int k = 0; k < kPrefetchAhead; ++k) prefetch(k);
  std::size_t l = 0;
  while (l < lines_.size()) {
    SearchLine& line = lines_[l];
    const ModelPoint& p = points_[line.point];
    prefetch(line.point + kPrefetchAhead);
    if (line.end != 0) {
      // An end: the object gives way to background going outwards along the tangent.
      line.centre = expected_point(line, p, &line.normal);
      ProfileSearch search = base;
      search.mode = ObservationMode::kEdge;
      search.band_px = std::min(base.band_px, options_.end_band_px);
      const bool dark = options_.observation == ObservationMode::kDarkLine ||
                        options_.observation == ObservationMode::kDarkRidge ||
                        (options_.observation == ObservationMode::kEdge &&
                         polarity_ == EdgePolarity::kDarkObject);
      const bool bright = options_.observation == ObservationMode::kBrightLine ||
                          (options_.observation == ObservationMode::kEdge &&
                           polarity_ == EdgePolarity::kBrightObject);
      search.expected_sign = dark ? 1 : bright ? -1 : 0;
      if (line.end < 0 && options_.start_end == StartEnd::kDarkRegion) {
        // The follicle: intensity falls where the face begins, going outwards from the base.
        search.expected_sign = -1;
        search.min_strength = static_cast<float>(options_.dark_region_min_step);
      }
      line.num_candidates = search_profile(frame, line.centre, line.normal, search, scratch_.data(),
                                           &candidates_[l * K]);
      ++l;
      continue;
    }
    // The lines of one sample point (both boundaries in edge mode) search along the same normal:
    // one profile across the object serves them all (edge mode: 2·(w + range) + 1 samples instead
    // of 2·(2·range + 1), w the half width). Samples sit at whole pixels from the centreline; a
    // line whose centre is not (fractional half width) reports offsets relative to its centre.
    std::size_t last = l;
    while (last + 1 < lines_.size() && lines_[last + 1].point == line.point &&
           lines_[last + 1].end == 0) {
      ++last;
    }
    int lo = std::numeric_limits<int>::max(), hi = std::numeric_limits<int>::min();
    for (std::size_t j = l; j <= last; ++j) {
      lines_[j].centre = expected_point(lines_[j], p, &lines_[j].normal);
      const int c = side_offset_px(lines_[j]);
      lo = std::min(lo, c - base.range_px - margin);
      hi = std::max(hi, c + base.range_px + margin);
    }
    sample_profile(frame, p.position, p.normal, lo, hi - lo + 1, base.band_px, profile);
    for (std::size_t j = l; j <= last; ++j) {
      const double c = lines_[j].side * options_.half_width_px;
      const int ci = side_offset_px(lines_[j]);
      ProfileSearch search = base;
      search.expected_sign = edge_sign(lines_[j]);
      search.ridge_mean_surround = lines_[j].mean_surround;
      search.ridge_position_from_profile = options_.ridge_position_from_profile;
      Candidate* found = &candidates_[j * K];
      int count =
          find_candidates(profile, ci - lo, static_cast<float>(c - ci), search, response, found);
      if (exclusion_ != nullptr) {
        // Vetoed candidates leave; the rest keep their order (strongest first).
        int kept = 0;
        for (int k = 0; k < count; ++k) {
          if (!exclusion_->excluded(lines_[j].centre + found[k].offset * lines_[j].normal)) {
            found[kept++] = found[k];
          }
        }
        count = kept;
      }
      lines_[j].num_candidates = count;
    }
    l = last + 1;
  }
}

}  // namespace sinew::rt
