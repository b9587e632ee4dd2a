#pragma once
/// Many whiskers at once, each a free beam (seed 000 §5.3) fitted to its own dark ridge, with a
/// stable identity and a status per frame. All memory is sized at construction for the whiskers
/// given; track() never allocates, throws or prints.
///
/// Each whisker's first node is its follicle: its end search along the tangent looks for the
/// face's edge (StartEnd::kDarkRegion), so the base moves with the face and may slide along its
/// edge but not along the whisker into the fur. Ridges are observed by their contrast relative to
/// the local backlight (ObservationMode::kDarkRidge), which neither a face's outline nor a thick
/// pole's sides answer.
///
/// A ridge is one whisker's: when a fit ends running along a neighbour's curve (within
/// claim_px over more than claim_fraction of its nodes), the whisker that moved more this frame
/// has jumped: its fit is discarded (Tracker::reject_last_frame) and it is reported lost for the
/// frame, so identities do not swap where whiskers cross or run side by side.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "rt/tracker.hpp"

namespace sinew::rt {

struct WhiskerTrackerOptions {
  /// Options of every whisker's tracker; the defaults below suit a faint whisker on a backlight.
  TrackerOptions tracker = default_tracker_options();
  /// Elements per whisker: its length / element_length_px, within [min_elements, max_elements].
  double element_length_px = 12.0;
  int min_elements = 4;
  int max_elements = 16;
  /// A whisker's section in pixel units (E, and the width h of a rectangular section of depth 1):
  /// only ratios matter to the fit; forces in physical units are the read-out's business.
  double young_modulus = 1000.0;
  double section_height_px = 2.0;
  /// A fit whose node moved more than this in one frame has slid or jumped off its whisker (a
  /// free beam is anchored by nothing but its ridge): it is discarded and the frame is lost,
  /// pixels, > 0. Should exceed the true motion per frame (the search reaches
  /// tracker.first_search_range_px).
  double max_jump_px = 20.0;
  /// See reacquire().
  double reacquire_radius_px = 30.0;
  double reacquire_angle_deg = 30.0;
  /// See the header comment.
  double claim_px = 1.5;
  double claim_fraction = 0.5;

  static TrackerOptions default_tracker_options();
  std::optional<std::string> validate() const;
};

/// Per whisker and frame.
struct WhiskerFrame {
  FrameStatus status = FrameStatus::kLost;
  bool on_neighbour = false;  ///< the fit ran onto another whisker and was discarded
  bool jumped = false;        ///< the fit moved more than max_jump_px and was discarded
  bool reacquired = false;    ///< restarted by reacquire() after this frame
  Eigen::Vector2d follicle = Eigen::Vector2d::Zero();  ///< first node
  Eigen::Vector2d tip = Eigen::Vector2d::Zero();       ///< last node
  double length_px = 0.0;                              ///< along the fitted nodes
  FrameSummary summary;                                ///< the whisker's own tracker summary
};

class WhiskerTracker {
 public:
  /// whiskers: each whisker's centreline on the first frame, follicle first (e.g. the points of
  /// detect_whiskers), at least 2 points and 2 px long. Check valid().
  WhiskerTracker(const std::vector<std::vector<Eigen::Vector2d>>& whiskers,
                 WhiskerTrackerOptions options = {});

  bool valid() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  int num_whiskers() const { return static_cast<int>(trackers_.size()); }
  const Tracker& whisker(int i) const { return trackers_[i]; }
  const WhiskerFrame& result(int i) const { return results_[i]; }

  /// Tracks every whisker on one frame; returns the wall time in seconds. No allocation.
  double track(const ImageView& frame) noexcept;

  /// Re-acquires the whiskers lost on the last tracked frame from whiskers detected on it
  /// (detect_whiskers; follicle first). A lost whisker takes the detected one whose follicle is
  /// nearest its own last follicle, within reacquire_radius_px, whose direction at the follicle
  /// is within reacquire_angle_deg of its own, and along which no tracked whisker runs (the
  /// claim test): never another whisker, a pole or a lick port, which detection does not report.
  /// Its state restarts on that curve (Tracker::restart_at) and it is reported as re-acquired.
  /// Outside the real-time contract (allocates); returns how many were re-acquired.
  int reacquire(const std::vector<std::vector<Eigen::Vector2d>>& detected);
  /// Any whisker lost on the last tracked frame.
  bool any_lost() const;

 private:
  // Fraction of whisker a's nodes within claim_px of whisker b's node polyline.
  double fraction_near(int a, int b) const;
  // Fraction of the points within claim_px of whisker b's node polyline.
  double fraction_near(const Eigen::Matrix2Xd& points, int b) const;

  WhiskerTrackerOptions options_;
  std::string error_;
  std::vector<Tracker> trackers_;
  std::vector<WhiskerFrame> results_;
  std::vector<double> moved_px_;  // max node displacement this frame, per whisker
  std::vector<Eigen::VectorXd> previous_;
};

}  // namespace sinew::rt
