#pragma once
/// The whole per-frame job of a whisker video, as sinew-track --whiskers and the Python module run
/// it: on the first frame, find the whiskers (detect_whiskers) and set up one tracker for them all;
/// on every frame, track them (WhiskerTracker::track, the real-time part), detect again and
/// associate when asked (a 25–100 fps camera, or lost whiskers), and read out the mechanics
/// (WhiskerReadoutModel, the first frame's fits being the whiskers at rest) and the contact with
/// the objects the detection saw. Set-up and detection allocate; the tracking does not.

#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "rt/load_fit.hpp"
#include "rt/whisker/contact.hpp"
#include "rt/whisker/detection.hpp"
#include "rt/whisker/readout.hpp"
#include "rt/whisker/taper_length.hpp"
#include "rt/whisker/whisker_tracker.hpp"

namespace sinew::rt {

/// When detection runs again after tracking: on every frame, only on frames with a lost whisker,
/// or never.
enum class Redetect { kEvery, kLost, kNever };
const char* to_string(Redetect redetect);
/// "every", "lost" or "never"; nullopt for anything else.
std::optional<Redetect> redetect_from_string(const std::string& name);

/// LoadFitOptions with the follicle angle fitted (fit_base_rotation): the session's contact fit.
/// Fitting the follicle's position too (fit_base_translation, `sinew-track
/// --fit-follicle-position`) helps where the load bends the whisker most at its follicle and
/// costs where it is small (docs/tracker.md, "The follicle's position in the load fit").
inline LoadFitOptions default_contact_fit() {
  LoadFitOptions o;
  o.fit_base_rotation = true;
  o.max_iterations = 12;
  return o;
}

struct WhiskerSessionOptions {
  WhiskerDetectionOptions detection;
  /// The trackers' options; ridge_min_background is set from the first detection's backlight
  /// (no ridge is looked for where detection saw the face or another dark object).
  WhiskerTrackerOptions tracker;
  WhiskerReadoutOptions readout;
  Redetect redetect = Redetect::kEvery;
  /// The frame (counted from the first one processed) whose fits are the whiskers at rest: Δκ,
  /// M0 and the contact load are changes from it. Choose one where nothing touches the whiskers;
  /// a whisker not tracked ok there takes its first ok frame after it. Until then the first
  /// frame's fits are the rest (and there is no contact load), ≥ 0.
  int rest_frame = 0;
  /// The rest shape is the mean of this many frames without contact from rest_frame on (each
  /// turned about its follicle onto the first: whisking turns the whole whisker), ≥ 1. Tracking
  /// noise in a single rest frame reads as a load on every later frame.
  int rest_frames = 1;
  /// Fit the contact load on frames in contact (contact_load below).
  bool contact_load = true;
  /// The contact-load fit's options (one load point: max_load_points is set to 1). Default: the
  /// follicle angle is fitted with the load (fit_base_rotation): the tracked first element's
  /// angle noise otherwise reads as a load (docs/tracker.md).
  LoadFitOptions contact_fit = default_contact_fit();

  std::optional<std::string> validate() const;
};

/// One whisker on the frame just processed, beside WhiskerTracker::result.
struct WhiskerSessionWhisker {
  /// The noise level of readout->moment (M0 from the curvature at the follicle), measured on the
  /// whisker itself: the RMS of M0 over its last kQuietFrames frames tracked ok,
  /// touching nothing, after its rest frame (nothing but tracking noise bends a whisker that
  /// touches nothing: whisking turns it about its follicle, which M0 does not see). The same
  /// noise is in M0 on frames in contact, so it is reported on every frame with a read-out; NaN
  /// until kQuietFramesMin such frames were seen (or detection, which sees contact, has not run).
  /// Where |M0| is within a few of it, the M0 column is noise: use the contact load's moment.
  double moment_sd = std::numeric_limits<double>::quiet_NaN();
  static constexpr int kQuietFrames = 64;
  static constexpr int kQuietFramesMin = 10;
  /// The read-out, for a whisker tracked ok (a lost whisker's state would be stale, and one
  /// placed on its detection without a fit has the detection's chords for rotations).
  std::optional<WhiskerReadout> readout;
  /// Contact with an object the detection of this frame saw, for a whisker tracked ok on a frame
  /// detection ran on.
  std::optional<WhiskerContact> contact;
  /// The force at the contact point that, with the follicle clamped at its tracked pose, best
  /// explains the whole tracked whisker against its rest shape (rt::LoadFit on the whisker's beam
  /// subdivided 4×: the load point moves with the contact in steps of a quarter element). For a
  /// whisker in contact after its rest frame. With an image scale (readout.physics.mm_per_px)
  /// in SI: newtons and newton-metres, the whisker's tapered cone (contact_fit_beam); without
  /// one, model units: the trackers' section (E, width h in pixels), lengths in pixels.
  /// When the fit found no equilibrium there is no load: force, point and moment are NaN (empty
  /// in the CSV, null in JSON). A load whose fit ran out of iterations is reported with
  /// converged false (LoadFitSummary).
  struct ContactLoad {
    static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
    bool converged = false;
    bool equilibrium = false;  ///< a load was found (LoadFitSummary::equilibrium)
    Eigen::Vector2d force = Eigen::Vector2d::Constant(kNaN);  ///< on the whisker, image axes
    Eigen::Vector2d point = Eigen::Vector2d::Constant(kNaN);  ///< where it acts, pixels
    double moment = kNaN;  ///< (point − follicle) × force: the contact's moment about the follicle
    double rms_px = 0.0;  ///< the fitted equilibrium's misfit to the tracked nodes
    /// The quasi-static estimate labs compute from curvature (Pammer et al. 2013): a force along
    /// the normal at the contact whose moment at the curvature window's centre p is E·I·Δκ there,
    /// f = E·I·Δκ / ((x_c − x_p) × n_c), and its moment about the follicle
    /// (x_c − x_0) × n_c · f (the cosines of their formula as cross products). Units as above
    /// (with a scale, E·I of the cone at p).
    double pammer_force = 0.0;
    double pammer_moment = 0.0;
    /// The force the whisker exerts on its follicle in the fitted equilibrium (the contact force,
    /// carried through the whisker: the follicle's reaction is its opposite), in the whisker's
    /// base frame: axial along the base tangent, positive pushing the whisker into the follicle
    /// (towards the face); lateral along the base normal (the tangent turned +90°, from +x
    /// towards +y like base_angle_deg). The base tangent is the fitted one (the follicle's angle
    /// is a parameter of the fit). Units of force above.
    double follicle_axial = kNaN;
    double follicle_lateral = kNaN;
    /// Standard deviations of the force's magnitude (along the contact normal), the moment and
    /// the follicle's two components, from the fit's covariance (LoadFit::covariance(): the
    /// tracked nodes' noise read off the fit's misfit, the follicle's own noise, and the fitted
    /// follicle angle's correlation with the force). The contact point is taken as known (it is
    /// the detection's), and the rest shape as exact. NaN without an equilibrium.
    double force_sd = kNaN;
    double moment_sd = kNaN;
    double follicle_axial_sd = kNaN;
    double follicle_lateral_sd = kNaN;
    /// The tracked nodes' noise the fit read off its misfit, pixels (LoadFitSummary::noise_px).
    double noise_px = kNaN;
  };
  std::optional<ContactLoad> contact_load;
  /// The force on the follicle, (axial, lateral) as in ContactLoad, every frame it is known: a
  /// found contact load's; zero where the whisker touches nothing (no external load holds it, so
  /// the follicle carries none); none otherwise (not tracked ok, detection did not run, or a
  /// contact whose load was not found or precedes the rest frame).
  std::optional<Eigen::Vector2d> follicle_force() const {
    if (contact_load && contact_load->equilibrium)
      return Eigen::Vector2d(contact_load->follicle_axial, contact_load->follicle_lateral);
    if (contact && !contact->touching) return Eigen::Vector2d::Zero();
    return std::nullopt;
  }
  /// The standard deviations of follicle_force(), where it is known: the contact load's, or
  /// zero where the whisker touches nothing.
  std::optional<Eigen::Vector2d> follicle_force_sd() const {
    if (contact_load && contact_load->equilibrium)
      return Eigen::Vector2d(contact_load->follicle_axial_sd, contact_load->follicle_lateral_sd);
    if (contact && !contact->touching) return Eigen::Vector2d::Zero();
    return std::nullopt;
  }
};

/// The beam a whisker's contact load is fitted on: the tracked beam's elements, with its shape at
/// the rest state `rest` as the reference, clamped at the follicle (which the fit holds at its
/// tracked pose). Without an image scale, the trackers' section (model units). With one
/// (physics.si()), the physical whisker's tapered cone (WhiskerPhysics::section_at at each
/// element's midpoint) with lengths still in pixels: EA and GA in newtons, EI in N·px² (EI over
/// the square of the metres per pixel), so that the fitted forces are in newtons.
common::BeamDescription contact_fit_beam(const common::BeamModel& tracked,
                                         const Eigen::VectorXd& rest,
                                         const WhiskerPhysics& physics = {});
common::BeamDescription contact_fit_beam(const Tracker& whisker, const Eigen::VectorXd& rest,
                                         const WhiskerPhysics& physics = {});

class WhiskerSession {
 public:
  explicit WhiskerSession(WhiskerSessionOptions options);

  /// Processes the next frame. Returns an empty string, or the error (bad options, no face on the
  /// first frame, a whisker the tracker cannot set up); after an error the session stays unset.
  std::string process(const ImageView& frame);

  bool started() const { return tracker_.has_value(); }
  int frames() const { return frames_; }
  /// The first frame's detection, and how long it took.
  const WhiskerDetection& first_detection() const { return first_; }
  double first_detection_seconds() const { return first_seconds_; }
  /// Valid once started().
  const WhiskerTracker& tracker() const { return *tracker_; }
  const WhiskerReadoutModel& readout_model(int w) const { return readouts_[w]; }
  /// Whisker w's physics as read out (valid once a frame was processed): the options' with, where
  /// they give an image scale and radii but no length, the whole length measured on the first
  /// frame (taper(w), rt/whisker/taper_length.hpp), else the tracked length as before.
  const WhiskerPhysics& physics(int w) const { return physics_[w]; }
  const TaperLength& taper(int w) const { return taper_[w]; }

  /// The frame just processed.
  double tracking_seconds() const { return tracking_seconds_; }
  bool redetected() const { return redetected_; }
  double redetect_seconds() const { return redetect_seconds_; }
  /// The read-out of the frame just processed (mechanics, contact, contact load), seconds.
  double readout_seconds() const { return readout_seconds_; }
  const WhiskerAssociation& association() const { return association_; }
  const WhiskerSessionWhisker& whisker(int w) const { return whiskers_[w]; }
  /// Distance to the objects of the last detection (see WhiskerDetection::object_distance).
  const std::vector<float>& object_distance() const { return object_distance_; }

 private:
  void take_rest(int w, const Eigen::VectorXd& u);
  void accumulate_rest(int w);
  // Adds this frame's M0 to the whisker's quiet ring when it touches nothing after its rest, and
  // sets its moment_sd.
  void moment_noise(int w);
  WhiskerSessionWhisker::ContactLoad fit_contact(int w, const WhiskerContact& contact);
  void pammer(int w, const WhiskerReadout& readout, const WhiskerContact& contact,
              WhiskerSessionWhisker::ContactLoad* load) const;

  WhiskerSessionOptions options_;
  WhiskerDetection first_;
  double first_seconds_ = 0.0;
  // The maps of every detection, reused from frame to frame.
  WhiskerDetectionWorkspace detection_workspace_;
  std::optional<WhiskerTracker> tracker_;
  std::vector<WhiskerReadoutModel> readouts_;
  std::vector<WhiskerPhysics> physics_;
  std::vector<TaperLength> taper_;
  std::vector<WhiskerSessionWhisker> whiskers_;
  // Per whisker: the rest state once taken, and the contact-load fit on the rest shape.
  std::vector<char> rest_taken_;
  std::vector<int> rest_count_;
  std::vector<Eigen::VectorXd> rest_sum_;
  std::vector<Eigen::VectorXd> rest_state_, contact_target_;
  std::vector<std::optional<LoadFit>> contact_fit_;
  std::vector<float> object_distance_;
  // Per whisker: the squared moments of the last kQuietFrames frames touching nothing (a ring),
  // their count.
  std::vector<Eigen::VectorXd> quiet_moments_;
  std::vector<int> quiet_count_;
  WhiskerAssociation association_;
  int frames_ = 0;
  double tracking_seconds_ = 0.0, redetect_seconds_ = 0.0, readout_seconds_ = 0.0;
  bool redetected_ = false;
};

}  // namespace sinew::rt
