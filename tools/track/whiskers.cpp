#include "tools/track/whiskers.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <optional>
#include <utility>

#include "rt/whisker/contact.hpp"
#include "rt/whisker/detection.hpp"
#include "rt/whisker/session.hpp"
#include "rt/whisker/whisker_tracker.hpp"
#include "tools/io/json_file.hpp"
#include "tools/track/frame_source.hpp"
#include "tools/track/overlay_sink.hpp"
#include "tools/track/whisker_hdf5.hpp"
#include "tools/track/whisker_plots.hpp"

namespace sinew::tools {

namespace {

rt::FaceSide parse_face(const std::string& face) {
  if (auto side = rt::face_side_from_string(face)) return *side;
  throw InputError("--face = \"" + face + "\" must be auto, left, right, top or bottom");
}

// A colour per identity (golden-ratio hues), so a whisker keeps its colour through the video.
cv::Scalar id_colour(int id) {
  cv::Mat hsv(1, 1, CV_8UC3,
              cv::Scalar(static_cast<int>(std::fmod(id * 0.618034, 1.0) * 180), 220, 255));
  cv::Mat bgr;
  cv::cvtColor(hsv, bgr, cv::COLOR_HSV2BGR);
  const cv::Vec3b c = bgr.at<cv::Vec3b>(0, 0);
  return cv::Scalar(c[0], c[1], c[2]);
}

// Ids in their colours, lost whiskers red, the follicle as a dot, a contact as a ring with the
// contact force as an arrow on the whisker (40 px for the largest force of the video so far) and
// the follicle's moment against it as an arc.
void draw_whiskers(cv::Mat& img, const rt::WhiskerTracker& tracker,
                   const std::vector<rt::WhiskerContact>& contacts,
                   const std::vector<std::optional<rt::WhiskerSessionWhisker::ContactLoad>>& loads,
                   double largest_force, double largest_moment, int frame) {
  for (int w = 0; w < tracker.num_whiskers(); ++w) {
    const rt::Tracker& t = tracker.whisker(w);
    const rt::WhiskerFrame& r = tracker.result(w);
    const bool lost = r.status == rt::FrameStatus::kLost;
    const cv::Scalar colour = lost ? cv::Scalar(0, 0, 255) : id_colour(w);
    for (int e = 0; e < t.model().num_elements(); ++e) {
      cv::Point2d prev;
      for (int k = 0; k <= 6; ++k) {
        const rt::CentrelinePoint p = t.centreline(e, k / 6.0);
        const cv::Point2d q(p.position.x(), p.position.y());
        if (k > 0) cv::line(img, prev, q, colour, 1, cv::LINE_AA);
        prev = q;
      }
    }
    const cv::Point2d f(r.follicle.x(), r.follicle.y());
    cv::circle(img, f, 3, colour, -1, cv::LINE_AA);
    cv::putText(img, std::to_string(w), cv::Point2d(r.tip.x() + 3, r.tip.y() + 3),
                cv::FONT_HERSHEY_SIMPLEX, 0.45, colour, 1, cv::LINE_AA);
    if (w < static_cast<int>(contacts.size()) && contacts[w].touching) {
      const cv::Point2d c(contacts[w].point.x(), contacts[w].point.y());
      cv::circle(img, c, 6, cv::Scalar(0, 255, 255), 2, cv::LINE_AA);
    }
    if (w < static_cast<int>(loads.size()) && loads[w] && largest_force > 0.0) {
      const Eigen::Vector2d head = loads[w]->point;
      const Eigen::Vector2d tail = head - 40.0 * loads[w]->force / largest_force;
      cv::arrowedLine(img, cv::Point2d(tail.x(), tail.y()), cv::Point2d(head.x(), head.y()),
                      cv::Scalar(0, 128, 255), 2, cv::LINE_AA, 0, 0.25);
      // The moment the follicle holds against it: an arc around the follicle, 270° for the
      // largest moment of the video so far, turning the way the moment turns.
      if (largest_moment > 0.0) {
        const double sweep = -270.0 * loads[w]->moment / largest_moment;
        const double start = std::atan2(r.tip.y() - r.follicle.y(), r.tip.x() - r.follicle.x());
        cv::ellipse(img, cv::Point2d(r.follicle.x(), r.follicle.y()), cv::Size(10, 10),
                    start * 180.0 / M_PI, 0.0, sweep, cv::Scalar(0, 128, 255), 2, cv::LINE_AA);
      }
    }
  }
  cv::putText(img, "frame " + std::to_string(frame), cv::Point(8, img.rows - 10),
              cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 255, 0), 1, cv::LINE_AA);
}

// The first frame's detection for a person asking why a whisker was not found: the frame
// magnified (faint whiskers are 1-2 px wide), the whiskers found in their id colours with their
// follicles and ids, the traces that were not in one colour per reason, and a legend with counts.
void write_detection_picture(const cv::Mat& grey, const rt::WhiskerDetection& d,
                             const std::string& path) {
  constexpr int kScale = 3;
  cv::Mat img;
  cv::resize(grey, img, cv::Size(), kScale, kScale, cv::INTER_CUBIC);
  cv::cvtColor(img, img, cv::COLOR_GRAY2BGR);
  const std::vector<std::pair<std::string, cv::Scalar>> reasons = {
      {"not smooth", cv::Scalar(0, 165, 255)},
      {"not at the face", cv::Scalar(255, 0, 255)},
      {"does not leave the face", cv::Scalar(0, 255, 255)},
      {"too dark", cv::Scalar(255, 128, 64)},
      {"too short", cv::Scalar(255, 255, 0)},
      {"runs along a longer whisker", cv::Scalar(160, 160, 160)},
      {"off the pad", cv::Scalar(0, 0, 255)}};
  auto polyline = [&](const std::vector<Eigen::Vector2d>& pts, const cv::Scalar& colour,
                      int width) {
    std::vector<cv::Point> q;
    for (const auto& p : pts) {
      q.emplace_back(static_cast<int>(std::lround(kScale * p.x())),
                     static_cast<int>(std::lround(kScale * p.y())));
    }
    cv::polylines(img, q, false, colour, width, cv::LINE_AA);
  };
  std::map<std::string, int> counts;
  for (const auto& r : d.rejected) {
    ++counts[r.reason];
    cv::Scalar colour(255, 255, 255);
    for (const auto& [reason, c] : reasons) {
      if (reason == r.reason) colour = c;
    }
    polyline(r.points, colour, 1);
  }
  for (std::size_t w = 0; w < d.whiskers.size(); ++w) {
    const rt::DetectedWhisker& found = d.whiskers[w];
    const cv::Scalar colour = id_colour(static_cast<int>(w));
    polyline(found.points, colour, 2);
    const cv::Point follicle(static_cast<int>(std::lround(kScale * found.follicle.x())),
                             static_cast<int>(std::lround(kScale * found.follicle.y())));
    cv::circle(img, follicle, 2 * kScale, colour, -1, cv::LINE_AA);
    const Eigen::Vector2d tip = kScale * found.points.back();
    cv::putText(img, std::to_string(w), cv::Point2d(tip.x() + 4, tip.y() + 4),
                cv::FONT_HERSHEY_SIMPLEX, 0.8, colour, 2, cv::LINE_AA);
  }
  int y = 24;
  auto legend = [&](const std::string& text, const cv::Scalar& colour) {
    cv::putText(img, text, cv::Point(10, y), cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(0, 0, 0), 4,
                cv::LINE_AA);
    cv::putText(img, text, cv::Point(10, y), cv::FONT_HERSHEY_SIMPLEX, 0.6, colour, 1, cv::LINE_AA);
    y += 22;
  };
  legend(std::to_string(d.whiskers.size()) + " whiskers found (face " + rt::to_string(d.face) + ")",
         cv::Scalar(255, 255, 255));
  for (const auto& [reason, colour] : reasons) {
    if (counts.count(reason)) legend(std::to_string(counts[reason]) + " " + reason, colour);
  }
  if (!cv::imwrite(path, img)) throw InputError(path + ": cannot write the detection picture");
}

nlohmann::json point(const Eigen::Vector2d& p) {
  return {p.x(), p.y()};
}

// The first JSON line: what detection found on the first frame, and the read-out's options.
nlohmann::json detection_line(const rt::WhiskerSession& session, int index, double detect_ms,
                              const rt::WhiskerReadoutOptions& readout) {
  const rt::WhiskerDetection& found = session.first_detection();
  nlohmann::json record = nlohmann::json::array();
  for (std::size_t w = 0; w < found.whiskers.size(); ++w) {
    nlohmann::json whisker = {{"id", w},
                              {"follicle", point(found.whiskers[w].follicle)},
                              {"length_px", found.whiskers[w].length_px},
                              {"contrast_percent", found.whiskers[w].contrast_percent}};
    // The cone the read-out uses: its whole length, measured from the whisker's darkness where
    // no length was given (rt/whisker/taper_length.hpp).
    if (readout.physics.si() && static_cast<int>(w) < session.tracker().num_whiskers()) {
      whisker["cone_length_mm"] =
          session.taper(static_cast<int>(w)).length_px * readout.physics.mm_per_px;
      whisker["cone_length_measured"] = session.taper(static_cast<int>(w)).measured;
    }
    record.push_back(whisker);
  }
  return nlohmann::json{
      {"detection",
       {{"frame", index},
        {"face", rt::to_string(found.face)},
        {"backlight", found.backlight},
        {"noise_percent", found.noise_percent},
        {"seed_contrast", found.seed_contrast},
        {"follow_contrast", found.follow_contrast},
        {"seconds", detect_ms * 1e-3},
        {"whiskers", record},
        {"readout",
         {{"mm_per_px", readout.physics.mm_per_px},
          {"young_modulus_gpa", readout.physics.young_modulus_gpa},
          {"base_radius_um", readout.physics.base_radius_um},
          {"tip_radius_um", readout.physics.tip_radius_um},
          {"length_mm", readout.physics.length_mm},
          {"axis_angle_deg", readout.axis_angle_deg},
          {"curvature_window_px", {readout.curvature_from_px, readout.curvature_to_px}}}}}}};
}

// The read-out's column names, which carry their units.
struct ReadoutKeys {
  std::string curvature, delta, moment;  // e.g. curvature_per_mm, delta_curvature_per_mm, m0_N_m
  std::string force_unit, torque_unit;   // "_N", "_N_m" with a scale, else "_model"
};

// Whisker w's JSON record of a frame; fills its table row (the value columns' order, NaN where
// empty), its time series point, and its contact and found contact load for the overlay.
nlohmann::json whisker_record(const rt::WhiskerSession& session, int w, const std::string& status,
                              const ReadoutKeys& keys, std::vector<double>& values,
                              WhiskerSeries& ts, int index, rt::WhiskerContact& contact,
                              std::optional<rt::WhiskerSessionWhisker::ContactLoad>& found_load,
                              double& largest_force, double& largest_moment) {
  const rt::WhiskerTracker& tracker = session.tracker();
  const rt::Tracker& t = tracker.whisker(w);
  const rt::WhiskerFrame& r = tracker.result(w);
  nlohmann::json nodes = nlohmann::json::array();
  for (int i = 0; i < t.num_nodes(); ++i) {
    const Eigen::Vector2d x = t.node_position(i);
    nodes.push_back({x.x(), x.y(), t.state()[3 * i + 2]});
  }
  nlohmann::json record = {{"id", w},
                           {"status", status},
                           {"nodes", nodes},
                           {"follicle", point(r.follicle)},
                           {"tip", point(r.tip)},
                           {"length_px", r.length_px},
                           {"on_neighbour", r.on_neighbour},
                           {"jumped", r.jumped},
                           {"out_of_order", r.out_of_order},
                           {"reacquired", r.reacquired},
                           {"inlier_fraction", r.summary.inlier_fraction}};
  // The read-out of a lost whisker's last state would be stale: none.
  ts.frame.push_back(index);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  ts.base_angle_deg.push_back(nan);
  ts.delta_curvature.push_back(nan);
  ts.moment.push_back(nan);
  ts.contact.push_back(nan);
  // Nor of a whisker placed on its detection without a fit (not converged): its node
  // rotations are the detection's chords', not an equilibrium's.
  values.assign(values.size(), nan);
  const rt::WhiskerSessionWhisker& sw = session.whisker(w);
  if (sw.readout) {
    const rt::WhiskerReadout& q = *sw.readout;
    ts.base_angle_deg.back() = q.base_angle_deg;
    ts.delta_curvature.back() = q.delta_curvature;
    ts.moment.back() = q.moment;
    record["base_angle_deg"] = q.base_angle_deg;
    record[keys.curvature] = q.curvature;
    record[keys.delta] = q.delta_curvature;
    record[keys.moment] = q.moment;
    if (std::isfinite(sw.moment_sd)) record["m0_sd" + keys.torque_unit] = sw.moment_sd;
    values = {r.follicle.x(),
              r.follicle.y(),
              r.tip.x(),
              r.tip.y(),
              r.length_px,
              q.base_angle_deg,
              q.curvature,
              q.delta_curvature,
              q.moment,
              nan,
              nan,
              nan,
              nan,
              nan,
              nan,
              nan,
              nan,
              nan,
              nan,
              nan,
              nan,
              nan};
    // Contact with a pole or another object the detection of this frame saw.
    if (sw.contact) {
      const rt::WhiskerContact& c = *sw.contact;
      contact = c;
      record["contact"] = c.touching;
      if (std::isfinite(c.distance_px)) record["object_distance_px"] = c.distance_px;
      values[9] = c.touching ? 1.0 : 0.0;
      ts.contact.back() = values[9];
      if (c.touching) {
        record["contact_arc_length_px"] = c.arc_length_px;
        record["contact_point"] = point(c.point);
        values[10] = c.arc_length_px;
      }
      if (sw.contact_load) {
        // Model units (the trackers' section, pixels) until the load is put in SI.
        const auto& load = *sw.contact_load;
        if (load.equilibrium) found_load = load;  // the overlay draws found loads only
        largest_force = std::max(largest_force, load.force.norm());
        largest_moment = std::max(largest_moment, std::abs(load.moment));
        record["contact_force" + keys.force_unit] = point(load.force);
        record["contact_moment" + keys.torque_unit] = load.moment;
        record["contact_load_point"] = point(load.point);
        record["contact_load_rms_px"] = load.rms_px;
        record["contact_load_converged"] = load.converged;
        record["pammer_force" + keys.force_unit] = load.pammer_force;
        record["pammer_moment" + keys.torque_unit] = load.pammer_moment;
        values[11] = load.force.x();
        values[12] = load.force.y();
        values[13] = load.moment;
        values[14] = load.pammer_moment;
        if (load.equilibrium) {
          record["contact_force_sd" + keys.force_unit] = load.force_sd;
          record["contact_moment_sd" + keys.torque_unit] = load.moment_sd;
          record["contact_load_noise_px"] = load.noise_px;
          values[17] = load.force_sd;
          values[18] = load.moment_sd;
        }
      }
    }
    // The follicle's load: the contact load's, zero when touching nothing (absent if not known).
    if (const auto f = sw.follicle_force()) {
      record["follicle_force_axial" + keys.force_unit] = f->x();
      record["follicle_force_lateral" + keys.force_unit] = f->y();
      values[15] = f->x();
      values[16] = f->y();
      const Eigen::Vector2d sd = *sw.follicle_force_sd();
      record["follicle_force_axial_sd" + keys.force_unit] = sd.x();
      record["follicle_force_lateral_sd" + keys.force_unit] = sd.y();
      values[19] = sd.x();
      values[20] = sd.y();
    }
    values[21] = sw.moment_sd;
  }
  return record;
}

// The HDF5 file (--hdf5): the table's columns, every whisker's node count, the units and the
// read-out's options as attributes.
std::unique_ptr<WhiskerHdf5Writer> open_hdf5(const WhiskerTrackArgs& args,
                                             const rt::WhiskerTracker& tracker,
                                             const std::vector<std::string>& value_columns, bool si,
                                             std::vector<std::vector<double>>& centrelines) {
  std::unique_ptr<WhiskerHdf5Writer> hdf5;
  std::vector<int> nodes;
  for (int w = 0; w < tracker.num_whiskers(); ++w) nodes.push_back(tracker.whisker(w).num_nodes());
  hdf5 = std::make_unique<WhiskerHdf5Writer>(args.hdf5, value_columns, nodes);
  centrelines.resize(nodes.size());
  hdf5->attribute("source", args.input);
  hdf5->attribute("units", si ? "lengths px (follicle, tip, nodes), curvature 1/mm, moment N m"
                              : "lengths px, curvature 1/px, moment pixel model units");
  hdf5->attribute("readout",
                  nlohmann::json{{"mm_per_px", args.readout.physics.mm_per_px},
                                 {"young_modulus_gpa", args.readout.physics.young_modulus_gpa},
                                 {"base_radius_um", args.readout.physics.base_radius_um},
                                 {"tip_radius_um", args.readout.physics.tip_radius_um},
                                 {"axis_angle_deg", args.readout.axis_angle_deg}}
                      .dump());
  return hdf5;
}

// The run's figures on the terminal: whisker-frames by status, latency, read-out and detection
// times, and the files written.
void print_whisker_summary(const WhiskerTrackArgs& args, int processed, int whiskers,
                           const std::string& source, const std::map<std::string, int>& statuses,
                           std::vector<double>& latencies, std::vector<double>& readout_times,
                           std::vector<double>& redetect_times, double detect_ms) {
  std::cout << "sinew-track: " << processed << " frames, " << whiskers << " whiskers from "
            << source << "\n  whisker-frames:";
  for (const auto& [k, v] : statuses) std::cout << " " << k << " " << v;
  std::cout << "\n  latency per frame (all whiskers): median " << percentile(latencies, 0.5)
            << " us, p99 " << percentile(latencies, 0.99) << " us; detection " << detect_ms
            << " ms\n  read-out per frame (mechanics, contact, contact load): median "
            << percentile(readout_times, 0.5) << " us, p99 " << percentile(readout_times, 0.99)
            << " us\n";
  if (!redetect_times.empty()) {
    std::cout << "  detection again (--redetect " << args.redetect
              << ", outside the real-time path): " << redetect_times.size() << " frames, median "
              << percentile(redetect_times, 0.5) << " ms\n";
  }
  std::cout << "  results: " << args.out << "\n";
  if (!args.overlay.empty()) std::cout << "  overlay: " << args.overlay << "\n";
  if (!args.detection_picture.empty()) {
    std::cout << "  detection picture: " << args.detection_picture << "\n";
  }
  if (!args.csv.empty()) std::cout << "  table: " << args.csv << "\n";
  if (!args.hdf5.empty()) std::cout << "  HDF5: " << args.hdf5 << "\n";
  if (!args.plots.empty()) std::cout << "  plots: " << args.plots << "/whisker_<id>.png\n";
}

// The session's options from the command line's.
rt::WhiskerSessionOptions session_options_of(const WhiskerTrackArgs& args) {
  rt::WhiskerSessionOptions session_options;
  session_options.detection.face = parse_face(args.face);
  session_options.detection.min_length_px = args.min_length_px;
  session_options.detection.repair_traces = args.repair_traces;
  session_options.tracker.associate_home_px = args.associate_home_px;
  session_options.tracker.held_ridge_px = args.held_ridge_px;
  session_options.tracker.associate_contrast_ratio = args.associate_contrast_ratio;
  session_options.tracker.tracker.start_clearance_px = args.start_clearance_px;
  session_options.tracker.tracker.start_mean_surround_px = args.start_mean_surround_px;
  session_options.tracker.tracker.ridge_position_from_profile = args.profile_position;
  session_options.readout = args.readout;
  session_options.rest_frame = args.rest_frame;
  session_options.rest_frames = args.rest_frames;
  session_options.contact_fit.fit_base_translation = args.fit_follicle_position;
  if (auto mode = rt::redetect_from_string(args.redetect)) {
    session_options.redetect = *mode;
  } else {
    throw InputError("--redetect " + args.redetect + ": must be every, lost or never");
  }
  return session_options;
}

// The read-out's column names (the CSV's, the HDF5 table's, the JSON keys), which carry their
// units, so that a reader needs no legend: the contact load's in newtons and newton-metres with a
// scale, else in model units.
ReadoutKeys readout_keys(bool si) {
  return {si ? "curvature_per_mm" : "curvature_per_px",
          si ? "delta_curvature_per_mm" : "delta_curvature_per_px", si ? "m0_N_m" : "m0_model",
          si ? "_N" : "_model", si ? "_N_m" : "_model"};
}

std::vector<std::string> value_columns_of(const ReadoutKeys& keys) {
  return {"follicle_x_px",
          "follicle_y_px",
          "tip_x_px",
          "tip_y_px",
          "length_px",
          "base_angle_deg",
          keys.curvature,
          keys.delta,
          keys.moment,
          "contact",
          "contact_arc_length_px",
          "contact_force_x" + keys.force_unit,
          "contact_force_y" + keys.force_unit,
          "contact_moment" + keys.torque_unit,
          "pammer_moment" + keys.torque_unit,
          "follicle_force_axial" + keys.force_unit,
          "follicle_force_lateral" + keys.force_unit,
          "contact_force_sd" + keys.force_unit,
          "contact_moment_sd" + keys.torque_unit,
          "follicle_force_axial_sd" + keys.force_unit,
          "follicle_force_lateral_sd" + keys.force_unit,
          "m0_sd" + keys.torque_unit};
}

// --csv FILE: the table, written to FILE.tmp (renamed when complete), its header first.
void open_csv(std::ofstream& csv, const std::string& path,
              const std::vector<std::string>& value_columns) {
  csv.open(path + ".tmp");
  if (!csv) throw InputError(path + ": cannot open file for writing");
  csv << "frame,id,status";
  for (const std::string& c : value_columns) csv << "," << c;
  csv << "\n";
  csv.precision(9);
}

}  // namespace

int run_whiskers(const WhiskerTrackArgs& args) {
  const rt::WhiskerSessionOptions session_options = session_options_of(args);
  rt::WhiskerSession session(session_options);
  FrameSource source(args.input, args.first, args.stride, args.count);

  std::ofstream out(args.out + ".tmp");
  if (!out) throw InputError(args.out + ": cannot open file for writing");
  OverlaySink overlay(args.overlay);

  if (auto err = args.readout.validate()) throw InputError(*err);
  const bool si = args.readout.physics.si();
  const ReadoutKeys keys = readout_keys(si);
  const std::vector<std::string> value_columns = value_columns_of(keys);
  std::ofstream csv;
  if (!args.csv.empty()) open_csv(csv, args.csv, value_columns);
  std::unique_ptr<WhiskerHdf5Writer> hdf5;

  std::vector<WhiskerSeries> series;
  std::vector<std::vector<double>> centrelines;
  std::vector<rt::WhiskerContact> contacts;
  std::vector<std::optional<rt::WhiskerSessionWhisker::ContactLoad>> loads;
  double largest_force = 0.0, largest_moment = 0.0;
  std::vector<double> latencies, redetect_times, readout_times;
  std::map<std::string, int> statuses;
  cv::Mat grey, colour;
  int index = 0, processed = 0;
  double detect_ms = 0.0;
  while (source.next(grey, index)) {
    const rt::ImageView view{grey.ptr<std::uint8_t>(), grey.cols, grey.rows,
                             static_cast<std::ptrdiff_t>(grey.step[0])};
    const bool first = !session.started();
    const std::string error = session.process(view);
    if (!error.empty()) {
      throw InputError(args.input + ": frame " + std::to_string(index) + ": " + error);
    }
    const rt::WhiskerTracker& tracker = session.tracker();
    if (first) {
      const rt::WhiskerDetection& found = session.first_detection();
      detect_ms = session.first_detection_seconds() * 1e3;
      out << detection_line(session, index, detect_ms, args.readout).dump() << "\n";
      if (!args.quiet) {
        std::cout << "sinew-track: " << found.whiskers.size() << " whiskers found on frame "
                  << index << " (face " << rt::to_string(found.face) << ", ridge noise "
                  << found.noise_percent << " %, seed " << found.seed_contrast << " %, follow "
                  << found.follow_contrast << " %; " << detect_ms << " ms)\n";
      }
      for (int w = 0; w < tracker.num_whiskers(); ++w) {
        series.emplace_back();
        series.back().id = w;
      }
      if (!args.hdf5.empty()) hdf5 = open_hdf5(args, tracker, value_columns, si, centrelines);
      if (!args.detection_picture.empty()) {
        // The session's detection again, keeping the traces it did not accept (the same options,
        // so the same whiskers).
        rt::WhiskerDetectionOptions o = session_options.detection;
        o.keep_rejected = true;
        write_detection_picture(grey, rt::detect_whiskers(view, o), args.detection_picture);
      }
    }
    const double seconds = session.tracking_seconds();
    latencies.push_back(seconds * 1e6);
    readout_times.push_back(session.readout_seconds() * 1e6);
    const bool redetect = session.redetected();
    const rt::WhiskerAssociation& association = session.association();
    if (redetect) redetect_times.push_back(session.redetect_seconds() * 1e3);
    const double redetect_ms = session.redetect_seconds() * 1e3;
    nlohmann::json line;
    line["frame"] = index;
    line["latency_us"] = seconds * 1e6;
    if (redetect) {
      line["redetect"] = {{"ms", redetect_ms},
                          {"detected", association.detected},
                          {"matched", association.matched},
                          {"restarted", association.restarted},
                          {"shift", point(association.shift)}};
    }
    nlohmann::json whiskers = nlohmann::json::array();
    contacts.assign(static_cast<std::size_t>(tracker.num_whiskers()), rt::WhiskerContact{});
    loads.assign(static_cast<std::size_t>(tracker.num_whiskers()), std::nullopt);
    for (int w = 0; w < tracker.num_whiskers(); ++w) {
      const rt::Tracker& t = tracker.whisker(w);
      const rt::WhiskerFrame& r = tracker.result(w);
      const std::string status = rt::to_string(r.status);
      ++statuses[status];
      const double nan = std::numeric_limits<double>::quiet_NaN();
      std::vector<double> values(value_columns.size(), nan);
      nlohmann::json record = whisker_record(session, w, status, keys, values, series[w], index,
                                             contacts[w], loads[w], largest_force, largest_moment);
      if (csv.is_open()) {
        csv << index << "," << w << "," << status;
        for (double v : values) {
          csv << ",";
          if (std::isfinite(v)) csv << v;
        }
        csv << "\n";
      }
      if (hdf5) {
        hdf5->add_row(index, w, status, values);
        std::vector<double>& c = centrelines[w];
        c.resize(3 * t.num_nodes());
        for (int i = 0; i < t.num_nodes(); ++i) {
          const bool lost = r.status == rt::FrameStatus::kLost;
          const Eigen::Vector2d x = t.node_position(i);
          c[3 * i] = lost ? nan : x.x();
          c[3 * i + 1] = lost ? nan : x.y();
          c[3 * i + 2] = lost ? nan : t.state()[3 * i + 2];
        }
      }
      whiskers.push_back(std::move(record));
    }
    line["whiskers"] = whiskers;
    if (hdf5) hdf5->add_frame(index, centrelines);
    out << line.dump() << "\n";

    if (overlay.enabled()) {
      cv::cvtColor(grey, colour, cv::COLOR_GRAY2BGR);
      draw_whiskers(colour, session.tracker(), contacts, loads, largest_force, largest_moment,
                    index);
      overlay.write(colour, index);
    }
    ++processed;
    if (!args.quiet && processed % 100 == 0) {
      std::cerr << "sinew-track: " << processed << " frames, median latency "
                << percentile(latencies, 0.5) << " us\n";
    }
  }
  out.close();
  if (processed == 0) {
    std::filesystem::remove(args.out + ".tmp");
    if (csv.is_open()) {
      csv.close();
      std::filesystem::remove(args.csv + ".tmp");
    }
    throw InputError(args.input + ": no frame to process (check --first/--count)");
  }
  std::filesystem::rename(args.out + ".tmp", args.out);
  if (csv.is_open()) {
    csv.close();
    std::filesystem::rename(args.csv + ".tmp", args.csv);
  }
  if (hdf5) hdf5->finish();
  if (!args.plots.empty()) {
    std::string error;
    if (!write_whisker_plots(args.plots, series, si ? "1/mm" : "1/px", si ? "N m" : "model units",
                             &error)) {
      throw InputError(error);
    }
  }
  if (!args.quiet) {
    print_whisker_summary(args, processed, session.tracker().num_whiskers(), source.description(),
                          statuses, latencies, readout_times, redetect_times, detect_ms);
  }
  return 0;
}

}  // namespace sinew::tools
