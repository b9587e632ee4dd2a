#include "tools/synth/whisker_pad.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <vector>

#include "common/beam/beam_model.hpp"
#include "common/beam/static_solver.hpp"

namespace sinew::tools::synth {

namespace {

namespace fs = std::filesystem;

constexpr int kFineElements = 64;  // simulation elements per whisker
constexpr double kFaceGrey = 25.0;
constexpr double kPoleGrey = 30.0;
constexpr double kPortGrey = 35.0;

struct Whisker {
  double length = 0.0;
  double kappa0 = 0.0;     // curvature at the base, 1/px (falls to half at the tip)
  double phi = 0.0;        // ellipse parameter of the follicle
  double fan = 0.0;        // rest angle from the face's normal, rad
  double contrast = 0.0;   // darkening at the base, grey levels
  Eigen::Matrix2Xd local;  // rest shape, follicle at 0, leaving along +x
};

// Rigid motion of the head at a frame: x ↦ R x + t about the face centre.
struct HeadPose {
  double rotation = 0.0;  // rad
  Eigen::Vector2d translation = Eigen::Vector2d::Zero();
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  Eigen::Vector2d apply(const Eigen::Vector2d& x) const {
    const double c = std::cos(rotation), s = std::sin(rotation);
    const Eigen::Vector2d d = x - centre;
    return centre + Eigen::Vector2d(c * d.x() - s * d.y(), s * d.x() + c * d.y()) + translation;
  }
  Eigen::Vector2d inverse(const Eigen::Vector2d& y) const {
    const double c = std::cos(rotation), s = std::sin(rotation);
    const Eigen::Vector2d d = y - translation - centre;
    return centre + Eigen::Vector2d(c * d.x() + s * d.y(), -s * d.x() + c * d.y());
  }
};

struct Scene {
  double scale = 1.0;
  Eigen::Vector2d face_centre;
  double rx = 0.0, ry = 0.0;
  std::vector<Whisker> whiskers;
  Eigen::Vector2d pole = Eigen::Vector2d::Zero();       // at rest (pole_at: at a frame)
  Eigen::Vector2d pole_axis = Eigen::Vector2d::Zero();  // unit, follicle to the pole at rest
  double pole_radius = 0.0;
  double pole_reach = 0.0;  // follicle to the pole's rest position, px
  Eigen::Vector2d port = Eigen::Vector2d::Zero(), port_half = Eigen::Vector2d::Zero();
};

// Rest shape: curvature κ0 (1 − s/2L), follicle at the origin, leaving along +x.
Eigen::Matrix2Xd rest_shape(double length, double kappa0) {
  Eigen::Matrix2Xd x(2, kFineElements + 1);
  x.col(0).setZero();
  const double h = length / kFineElements;
  double angle = 0.0;
  for (int i = 1; i <= kFineElements; ++i) {
    const double s_mid = (i - 0.5) * h;
    const double kappa = kappa0 * (1.0 - 0.5 * s_mid / length);
    const double a_mid = angle + 0.5 * kappa * h;
    x.col(i) = x.col(i - 1) + h * Eigen::Vector2d(std::cos(a_mid), std::sin(a_mid));
    angle += kappa * h;
  }
  return x;
}

Eigen::Vector2d follicle_in_head(const Scene& sc, const Whisker& w) {
  return sc.face_centre + Eigen::Vector2d(sc.rx * std::cos(w.phi), sc.ry * std::sin(w.phi));
}

// The face's outward normal direction at a follicle, as an angle.
double normal_angle(const Scene& sc, const Whisker& w) {
  return std::atan2(std::sin(w.phi) / sc.ry, std::cos(w.phi) / sc.rx);
}

double base_angle(const WhiskerPadOptions& o, int frame, int k) {
  const double amplitude = 10.0 * M_PI / 180.0;
  return amplitude * std::sin(2.0 * M_PI * o.whisk_hz * frame / o.fps + 0.15 * k);
}

HeadPose head_pose(const WhiskerPadOptions& o, const Scene& sc, int frame) {
  HeadPose p;
  p.centre = sc.face_centre;
  if (!o.face_motion) return p;
  p.translation = sc.scale * Eigen::Vector2d(8.0 * std::sin(2.0 * M_PI * frame / 120.0),
                                             5.0 * std::sin(2.0 * M_PI * frame / 90.0));
  p.rotation = 3.0 * M_PI / 180.0 * std::sin(2.0 * M_PI * frame / 150.0);
  return p;
}

// The undeformed whisker in the image at a frame.
Eigen::Matrix2Xd placed(const WhiskerPadOptions& o, const Scene& sc, int frame, int k) {
  const Whisker& w = sc.whiskers[k];
  const HeadPose pose = head_pose(o, sc, frame);
  const double a = normal_angle(sc, w) + w.fan + base_angle(o, frame, k) + pose.rotation;
  const Eigen::Vector2d f = pose.apply(follicle_in_head(sc, w));
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix2Xd x(2, w.local.cols());
  for (Eigen::Index i = 0; i < x.cols(); ++i) {
    const Eigen::Vector2d p = w.local.col(i);
    x.col(i) = f + Eigen::Vector2d(c * p.x() - s * p.y(), s * p.x() + c * p.y());
  }
  return x;
}

double half_width(double s, double length) {
  return 0.5 * (3.0 - 2.0 * s / length);
}

Scene build_scene(const WhiskerPadOptions& o) {
  Scene sc;
  sc.scale = std::min(o.width / 640.0, o.height / 480.0);
  sc.face_centre = Eigen::Vector2d(-70.0 * sc.scale, 0.5 * o.height);
  sc.rx = 200.0 * sc.scale;
  sc.ry = 0.62 * o.height;
  const int n = o.whiskers;
  for (int k = 0; k < n; ++k) {
    Whisker w;
    const double y = 0.5 * o.height + (n > 1 ? (k / (n - 1.0) - 0.5) : 0.0) * 0.56 * o.height;
    w.phi = std::asin(std::clamp((y - sc.face_centre.y()) / sc.ry, -0.95, 0.95));
    w.length = sc.scale * (140.0 + 80.0 * ((k * 37) % 7) / 6.0);
    w.kappa0 = 1.0 / (350.0 * sc.scale);
    if (k == 2) w.kappa0 = 5.0e-3 / sc.scale;  // the crossing pair curve towards each other
    if (k == 3) w.kappa0 = -5.0e-3 / sc.scale;
    w.fan = (k - 0.5 * (n - 1)) * 2.0 * M_PI / 180.0;
    const int rank = (3 * k) % n;  // the faint ones are spread over the pad
    w.contrast =
        o.contrast_min + (n > 1 ? (o.contrast_max - o.contrast_min) * rank / (n - 1.0) : 0.0);
    w.local = rest_shape(w.length, w.kappa0);
    sc.whiskers.push_back(w);
  }
  // The pole: on the last whisker's sweep at 60 % of its length, reached at half the protraction.
  sc.pole_radius = 8.0 * sc.scale;
  if (o.pole && n > 0) {
    const int k = n - 1;
    const Whisker& w = sc.whiskers[k];
    const int c = static_cast<int>(std::lround(0.6 * kFineElements));
    const double s_c = w.length * c / kFineElements;
    // Undeformed at half the amplitude, head at rest; the sweep direction is the rotation's.
    const HeadPose rest;
    const double a = normal_angle(sc, w) + w.fan + 0.5 * 10.0 * M_PI / 180.0;
    const Eigen::Vector2d f = follicle_in_head(sc, w);
    const Eigen::Vector2d p = w.local.col(c);
    const Eigen::Vector2d x = f + Eigen::Vector2d(std::cos(a) * p.x() - std::sin(a) * p.y(),
                                                  std::sin(a) * p.x() + std::cos(a) * p.y());
    const Eigen::Vector2d r = x - f;
    const Eigen::Vector2d sweep = Eigen::Vector2d(-r.y(), r.x()).normalized();
    sc.pole = x + (sc.pole_radius + half_width(s_c, w.length)) * sweep;
    sc.pole_axis = (sc.pole - f).normalized();
    sc.pole_reach = (sc.pole - f).norm();
  }
  sc.port = Eigen::Vector2d(0.82 * o.width, 0.82 * o.height);
  sc.port_half = sc.scale * Eigen::Vector2d(35.0, 17.0);
  return sc;
}

// The pole at a frame: slid from its rest position (60 % of the pressed whisker's length) towards
// the follicle by up to pole_travel of the length and back, one cosine period over the sequence,
// along the line from the follicle. Towards the tip the contact's simple rule (the node nearest the
// pole, pushed along the whisker's normal there) breaks down as the tip passes the pole.
Eigen::Vector2d pole_at(const WhiskerPadOptions& o, const Scene& sc, int frame) {
  if (o.pole_travel == 0.0 || o.whiskers < 1) return sc.pole;
  const double length = sc.whiskers[o.whiskers - 1].length;
  const double slide =
      -o.pole_travel * length * 0.5 * (1.0 - std::cos(2.0 * M_PI * frame / o.frames));
  return sc.pole + slide * sc.pole_axis;
}

struct ContactState {
  bool touching = false;
  int node = 0;
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
  Eigen::Vector2d force = Eigen::Vector2d::Zero();
};

// The last whisker against the pole: clamped at its follicle, loaded at the fine node nearest the
// pole by a frictionless contact: the force lies along the deflected whisker's normal at that node
// (a frictionless pole cannot push along the whisker) and puts the node on the pole's surface
// (offset by the whisker's half width). Returns the deflected nodes.
//
// Until 2026-12-06 the force lay along the line from the pole's centre through the node, which is
// the whisker's normal only where the node is the exact point of closest approach: with fine
// nodes 2.2 px apart on a pole of radius 8 it carried a component along the whisker of 7 % of the
// force (median over the sliding pole's contact frames; 12 % at most) that no frictionless
// contact has, and the trackers' contact force (fitted along the normal) was scored against it.
Eigen::Matrix2Xd press_on_pole(const Eigen::Vector2d& pole, double pole_radius,
                               const Eigen::Matrix2Xd& undeformed, double length,
                               ContactState* contact) {
  *contact = ContactState{};
  const Eigen::Index last = undeformed.cols() - 1;
  int c = 0;
  double best = std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 1; i <= last; ++i) {
    const double d = (undeformed.col(i) - pole).norm();
    if (d < best) {
      best = d;
      c = static_cast<int>(i);
    }
  }
  // Centre to centre at contact: the pole's radius and the whisker's half width at node k.
  const auto reach = [&](int k) {
    return pole_radius + half_width(length * k / kFineElements, length);
  };
  if (best >= reach(c)) return undeformed;

  common::BeamMaterial m;
  m.E = 1000.0;
  m.G = m.E / 2.6;
  m.A = 2.0;
  m.I = 8.0 / 12.0;
  common::BeamDescription d = common::BeamDescription::uniform(undeformed, m);
  d.clamp(0);
  const common::BeamModel model(d);
  common::StaticSolverOptions so;
  so.load_steps = 4;
  common::StaticBeamSolver solver(model, so);
  Eigen::VectorXd loads = Eigen::VectorXd::Zero(model.num_dofs());
  Eigen::VectorXd u = Eigen::VectorXd::Zero(model.num_dofs());
  auto position = [&](Eigen::Index k) -> Eigen::Vector2d {
    return undeformed.col(k) + u.segment<2>(3 * k);
  };
  // The unit normal of the whisker at node k in the state u (central difference of the nodes,
  // one-sided at the tip), turned away from the pole.
  auto normal_at = [&](Eigen::Index k) -> Eigen::Vector2d {
    const Eigen::Vector2d t = position(std::min(k + 1, last)) - position(k - 1);  // k ≥ 1
    Eigen::Vector2d n(-t.y(), t.x());
    n.normalize();
    return n.dot(position(k) - pole) < 0.0 ? Eigen::Vector2d(-n) : n;
  };
  Eigen::Vector2d n = normal_at(c);
  auto gap = [&](double F) {
    loads.setZero();
    loads.segment<2>(3 * c) = F * n;
    u.setZero();
    const auto summary = solver.solve(loads, u);
    if (!summary.converged()) {
      throw std::runtime_error("whisker-pad: the contact solve did not converge (" +
                               std::string(summary.message) + ")");
    }
    return (position(c) - pole).norm() - reach(c);
  };
  // Bracket and bisect the force's magnitude along n (to 1e-9 of it) until the node touches the
  // pole; then take the deflected whisker's node nearest the pole and its normal there, until
  // neither changes.
  double hi = 0.0;
  for (int turn = 0; turn < 50; ++turn) {
    double lo = 0.0;
    hi = model.max_bending_stiffness() / (length * length);
    while (gap(hi) < 0.0) hi *= 2.0;
    for (int it = 0; it < 60 && hi - lo > 1e-9 * hi; ++it) {
      const double mid = 0.5 * (lo + hi);
      if (gap(mid) < 0.0) {
        lo = mid;
      } else {
        hi = mid;
      }
    }
    gap(hi);
    int nearest = c;
    for (Eigen::Index i = 1; i <= last; ++i) {
      if ((position(i) - pole).norm() < (position(nearest) - pole).norm()) {
        nearest = static_cast<int>(i);
      }
    }
    const Eigen::Vector2d turned = normal_at(nearest);
    const bool settled = nearest == c && (turned - n).norm() < 1e-9;
    c = nearest;
    n = turned;
    if (settled) break;
  }
  gap(hi);
  contact->touching = true;
  contact->node = c;
  contact->force = hi * n;
  Eigen::Matrix2Xd x = undeformed;
  for (Eigen::Index i = 0; i <= last; ++i) x.col(i) = position(i);
  contact->point = x.col(c);
  return x;
}

void draw_whisker(cv::Mat& dark, const Eigen::Matrix2Xd& x, double length, double contrast) {
  // Samples every 0.25 px along the chords; each darkens the pixels within its half width
  // (anti-aliased: coverage clamp(hw + 0.5 − d, 0, 1)), the darkest sample wins.
  double s0 = 0.0;
  for (Eigen::Index i = 0; i + 1 < x.cols(); ++i) {
    const Eigen::Vector2d a = x.col(i), b = x.col(i + 1);
    const double seg = (b - a).norm();
    const int steps = std::max(1, static_cast<int>(std::ceil(seg / 0.25)));
    for (int k = 0; k <= steps; ++k) {
      const double t = static_cast<double>(k) / steps;
      const Eigen::Vector2d p = a + t * (b - a);
      const double s = s0 + t * seg;
      const double hw = half_width(s, length);
      const double c = contrast * (1.0 - 0.6 * s / length);
      const int x0 = static_cast<int>(std::floor(p.x() - hw - 1)),
                x1 = static_cast<int>(std::ceil(p.x() + hw + 1));
      const int y0 = static_cast<int>(std::floor(p.y() - hw - 1)),
                y1 = static_cast<int>(std::ceil(p.y() + hw + 1));
      for (int yy = std::max(0, y0); yy <= std::min(dark.rows - 1, y1); ++yy) {
        float* row = dark.ptr<float>(yy);
        for (int xx = std::max(0, x0); xx <= std::min(dark.cols - 1, x1); ++xx) {
          const double d = std::hypot(xx - p.x(), yy - p.y());
          const double cover = std::clamp(hw + 0.5 - d, 0.0, 1.0);
          row[xx] = std::max(row[xx], static_cast<float>(c * cover));
        }
      }
    }
    s0 += seg;
  }
}

nlohmann::json xy(const Eigen::Vector2d& p) {
  return {p.x(), p.y()};
}

}  // namespace

void write_whisker_pad(const WhiskerPadOptions& o, const std::string& out_dir) {
  const Scene sc = build_scene(o);
  const fs::path dir(out_dir), frames_dir = dir / "frames";
  fs::create_directories(frames_dir);
  for (const auto& entry : fs::directory_iterator(frames_dir)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("f_", 0) == 0 && entry.path().extension() == ".png") fs::remove(entry.path());
  }
  std::ofstream truth(dir / "truth.jsonl");
  if (!truth) throw std::runtime_error((dir / "truth.jsonl").string() + ": cannot write");

  // Backlight: graded left to right and top to bottom.
  cv::Mat backlight(o.height, o.width, CV_32F);
  for (int y = 0; y < o.height; ++y) {
    for (int x = 0; x < o.width; ++x) {
      backlight.at<float>(y, x) =
          static_cast<float>(140.0 + 50.0 * x / o.width + 15.0 * std::sin(M_PI * y / o.height));
    }
  }
  cv::RNG rng(o.seed);
  cv::Mat dark(o.height, o.width, CV_32F), image(o.height, o.width, CV_32F), noise, frame8;
  for (int frame = 0; frame < o.frames; ++frame) {
    const HeadPose pose = head_pose(o, sc, frame);
    const Eigen::Vector2d pole = pole_at(o, sc, frame);
    // Face (anti-aliased ellipse in head coordinates), pole and lick port over the backlight.
    for (int y = 0; y < o.height; ++y) {
      for (int x = 0; x < o.width; ++x) {
        const Eigen::Vector2d h = pose.inverse(Eigen::Vector2d(x, y)) - sc.face_centre;
        const double f = (std::hypot(h.x() / sc.rx, h.y() / sc.ry) - 1.0) * std::min(sc.rx, sc.ry);
        double cover = std::clamp(0.5 - f, 0.0, 1.0);
        double grey = kFaceGrey;
        const double dp = std::hypot(x - pole.x(), y - pole.y()) - sc.pole_radius;
        if (o.pole && 0.5 - dp > cover) {
          cover = std::clamp(0.5 - dp, 0.0, 1.0);
          grey = kPoleGrey;
        }
        const Eigen::Vector2d q(std::abs(x - sc.port.x()) - sc.port_half.x() + 6.0,
                                std::abs(y - sc.port.y()) - sc.port_half.y() + 6.0);
        const double dq = std::hypot(std::max(q.x(), 0.0), std::max(q.y(), 0.0)) +
                          std::min(std::max(q.x(), q.y()), 0.0) - 6.0;
        if (o.lick_port && 0.5 - dq > cover) {
          cover = std::clamp(0.5 - dq, 0.0, 1.0);
          grey = kPortGrey;
        }
        const float b = backlight.at<float>(y, x);
        image.at<float>(y, x) = static_cast<float>(b * (1.0 - cover) + grey * cover);
      }
    }
    dark.setTo(0.0f);
    nlohmann::json whiskers = nlohmann::json::array();
    for (int k = 0; k < o.whiskers; ++k) {
      const Whisker& w = sc.whiskers[k];
      Eigen::Matrix2Xd x = placed(o, sc, frame, k);
      ContactState contact;
      if (o.pole && k == o.whiskers - 1)
        x = press_on_pole(pole, sc.pole_radius, x, w.length, &contact);
      draw_whisker(dark, x, w.length, w.contrast);
      nlohmann::json centreline = nlohmann::json::array();
      for (Eigen::Index i = 0; i < x.cols(); ++i) centreline.push_back(xy(x.col(i)));
      nlohmann::json c = nullptr;
      if (contact.touching) {
        c = {{"point", xy(contact.point)},
             {"arc_length_px", w.length * contact.node / kFineElements},
             {"force", xy(contact.force)}};
      }
      whiskers.push_back({{"id", k},
                          {"follicle", xy(x.col(0))},
                          {"base_angle_deg", base_angle(o, frame, k) * 180.0 / M_PI},
                          {"length_px", w.length},
                          {"contrast", w.contrast},
                          {"centreline", centreline},
                          {"contact", c}});
    }
    // Whiskers lie in front of the face's edge only where the backlight shows: they darken what
    // is there, never below the face's grey.
    cv::subtract(image, dark, image);
    cv::max(image, std::min(kFaceGrey, kPoleGrey) - 10.0, image);
    noise.create(image.size(), CV_32F);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, o.noise);
    cv::add(image, noise, noise);
    noise.convertTo(frame8, CV_8U);  // rounds and saturates to [0, 255]
    char name[32];
    std::snprintf(name, sizeof name, "f_%04d.png", frame);
    if (!cv::imwrite((frames_dir / name).string(), frame8)) {
      throw std::runtime_error((frames_dir / name).string() + ": cannot write");
    }
    truth << nlohmann::json{{"frame", frame},
                            {"face",
                             {{"translation", xy(pose.translation)},
                              {"rotation_deg", pose.rotation * 180.0 / M_PI}}},
                            {"pole", {{"centre", xy(pole)}, {"radius", sc.pole_radius}}},
                            {"whiskers", whiskers}}
                 .dump()
          << "\n";
  }
}

}  // namespace sinew::tools::synth
