#include "rt/whisker/session.hpp"

#include <chrono>

#include "common/timing.hpp"

namespace sinew::rt {

using common::seconds_since;

const char* to_string(Redetect redetect) {
  switch (redetect) {
    case Redetect::kEvery:
      return "every";
    case Redetect::kLost:
      return "lost";
    case Redetect::kNever:
      return "never";
  }
  return "?";
}

std::optional<Redetect> redetect_from_string(const std::string& name) {
  for (Redetect r : {Redetect::kEvery, Redetect::kLost, Redetect::kNever}) {
    if (name == to_string(r)) return r;
  }
  return std::nullopt;
}

std::optional<std::string> WhiskerSessionOptions::validate() const {
  if (auto err = detection.validate()) return "detection: " + *err;
  if (auto err = tracker.validate()) return *err;
  if (auto err = readout.validate()) return "read-out: " + *err;
  return std::nullopt;
}

WhiskerSession::WhiskerSession(WhiskerSessionOptions options) : options_(std::move(options)) {}

std::string WhiskerSession::process(const ImageView& frame) {
  if (!tracker_) {
    if (auto err = options_.validate()) return *err;
    const auto t0 = std::chrono::steady_clock::now();
    first_ = detect_whiskers(frame, options_.detection);
    first_seconds_ = seconds_since(t0);
    if (!first_.error.empty()) return first_.error;
    std::vector<std::vector<Eigen::Vector2d>> traces;
    for (const auto& w : first_.whiskers) traces.push_back(w.points);
    WhiskerTrackerOptions track_options = options_.tracker;
    track_options.tracker.ridge_min_background =
        options_.detection.dark_fraction * first_.backlight;
    WhiskerTracker tracker(traces, track_options);
    if (!tracker.valid()) return tracker.error();
    std::vector<WhiskerReadoutModel> readouts;
    for (int w = 0; w < tracker.num_whiskers(); ++w) {
      readouts.emplace_back(tracker.whisker(w).model(), options_.readout);
      if (!readouts.back().valid()) {
        return "whisker " + std::to_string(w) + ": " + readouts.back().error();
      }
    }
    tracker_.emplace(std::move(tracker));
    readouts_ = std::move(readouts);
    whiskers_.resize(readouts_.size());
  }
  tracking_seconds_ = tracker_->track(frame);
  // The first frame's fits are the whiskers at rest (Δκ and M0 are changes from them).
  if (frames_ == 0) {
    for (int w = 0; w < tracker_->num_whiskers(); ++w) {
      readouts_[w].set_rest(tracker_->whisker(w).state());
    }
  }
  ++frames_;
  // Detection again, outside the real-time path: the whiskers are matched to it in their order
  // along the face, and lost or misplaced ones restart on theirs.
  association_ = WhiskerAssociation{};
  redetected_ = options_.redetect == Redetect::kEvery ||
                (options_.redetect == Redetect::kLost && tracker_->any_lost());
  redetect_seconds_ = 0.0;
  bool have_objects = false;
  if (redetected_) {
    const auto t0 = std::chrono::steady_clock::now();
    WhiskerDetection again = detect_whiskers(frame, options_.detection);
    std::vector<std::vector<Eigen::Vector2d>> traces;
    for (const auto& w : again.whiskers) traces.push_back(w.points);
    if (again.error.empty()) association_ = tracker_->associate(frame, traces);
    object_distance_ = std::move(again.object_distance);
    have_objects = again.error.empty();
    redetect_seconds_ = seconds_since(t0);
  }
  for (int w = 0; w < tracker_->num_whiskers(); ++w) {
    WhiskerSessionWhisker& out = whiskers_[w];
    out = WhiskerSessionWhisker{};
    if (tracker_->result(w).status != FrameStatus::kOk) continue;
    const Tracker& t = tracker_->whisker(w);
    out.readout = readouts_[w].evaluate(t.state());
    if (have_objects) {
      out.contact = object_distance_.empty()
                        ? WhiskerContact{}
                        : find_contact(t, object_distance_.data(), frame.width, frame.height);
    }
  }
  return {};
}

}  // namespace sinew::rt
