#include "common/beam/beam_model.hpp"

#include <Eigen/QR>
#include <cmath>
#include <sstream>

namespace sinew::common {

namespace {
std::string format_value(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}
}  // namespace

std::optional<std::string> BeamMaterial::validate() const {
  const std::pair<const char*, double> fields[] = {{"E", E}, {"G", G}, {"A", A}, {"I", I}};
  for (const auto& [name, value] : fields) {
    if (!std::isfinite(value)) return std::string("material.") + name + " is not finite";
    if (!(value > 0.0)) {
      return std::string("material.") + name + " = " + format_value(value) + " must be > 0";
    }
  }
  return std::nullopt;
}

BeamDescription BeamDescription::uniform(const Eigen::Matrix2Xd& rest_positions,
                                         const BeamMaterial& material) {
  BeamDescription d;
  d.rest_positions = rest_positions;
  const Eigen::Index n = rest_positions.cols();
  d.sections.assign(n > 1 ? n - 1 : 0, material.section());
  return d;
}

void BeamDescription::fix(int node, BeamDof dof) {
  if (fixed.empty()) fixed.assign(3 * rest_positions.cols(), 0);
  fixed[3 * node + static_cast<int>(dof)] = 1;
}

void BeamDescription::clamp(int node) {
  fix(node, BeamDof::kUx);
  fix(node, BeamDof::kUy);
  fix(node, BeamDof::kTheta);
}

std::optional<std::string> BeamDescription::validate() const {
  const Eigen::Index n = rest_positions.cols();
  if (n < 2) return "a beam needs at least 2 nodes, got " + std::to_string(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!rest_positions.col(i).allFinite()) {
      return "nodes[" + std::to_string(i) + "] has a non-finite coordinate";
    }
  }
  for (Eigen::Index e = 0; e + 1 < n; ++e) {
    const double length = (rest_positions.col(e + 1) - rest_positions.col(e)).norm();
    const double scale = std::max(rest_positions.col(e).norm(), rest_positions.col(e + 1).norm());
    if (!(length > 1e-12 * std::max(scale, 1.0))) {
      return "element " + std::to_string(e) + " (nodes " + std::to_string(e) + ", " +
             std::to_string(e + 1) + ") has zero length: the two nodes coincide";
    }
  }
  if (static_cast<Eigen::Index>(sections.size()) != n - 1) {
    return "expected " + std::to_string(n - 1) + " element sections, got " +
           std::to_string(sections.size());
  }
  for (std::size_t e = 0; e < sections.size(); ++e) {
    const auto& s = sections[e];
    const std::pair<const char*, double> fields[] = {{"EA", s.EA}, {"GA", s.GA}, {"EI", s.EI}};
    for (const auto& [name, value] : fields) {
      if (!std::isfinite(value) || !(value > 0.0)) {
        return "element " + std::to_string(e) + ": " + name + " = " + format_value(value) +
               " must be finite and > 0";
      }
    }
  }
  if (!prestress.empty() && static_cast<Eigen::Index>(prestress.size()) != n - 1) {
    return "expected 0 or " + std::to_string(n - 1) + " pre-stress entries, got " +
           std::to_string(prestress.size());
  }
  for (std::size_t e = 0; e < prestress.size(); ++e) {
    const auto& p = prestress[e];
    if (!std::isfinite(p.N0) || !std::isfinite(p.V0) || !std::isfinite(p.M0)) {
      return "element " + std::to_string(e) + ": pre-stress is not finite";
    }
  }
  if (!fixed.empty() && static_cast<Eigen::Index>(fixed.size()) != 3 * n) {
    return "expected 0 or " + std::to_string(3 * n) + " fixed-dof flags, got " +
           std::to_string(fixed.size());
  }
  return std::nullopt;
}

BeamModel::BeamModel(BeamDescription description) {
  if (auto err = description.validate()) {
    error_ = *err;
    return;
  }
  description_ = std::move(description);
  const int n = num_nodes();
  references_.reserve(n - 1);
  for (int e = 0; e + 1 < n; ++e) {
    references_.push_back(make_beam_element_reference(description_.rest_positions.col(e),
                                                      description_.rest_positions.col(e + 1)));
    total_length_ += references_.back().length;
    max_EI_ = std::max(max_EI_, description_.sections[e].EI);
  }
  fixed_mask_ =
      description_.fixed.empty() ? std::vector<unsigned char>(3 * n, 0) : description_.fixed;
  rigid_motions_constrained_ = compute_rigid_motions_constrained();
}

int BeamModel::num_fixed_dofs() const {
  int count = 0;
  for (unsigned char f : fixed_mask_) count += f ? 1 : 0;
  return count;
}

bool BeamModel::compute_rigid_motions_constrained() const {
  // A rigid motion (a, b, ω) moves node i by (a − ω·Y_i, b + ω·X_i) and turns it by ω. It is
  // blocked when the fixed dofs' rows of this 3n x 3 map have rank 3.
  const int rows = num_fixed_dofs();
  if (rows < 3) return false;
  Eigen::MatrixXd R(rows, 3);
  int r = 0;
  const Eigen::Vector2d centre = rest_positions().rowwise().mean();
  const double scale = std::max(total_length_, 1e-300);
  for (int i = 0; i < num_nodes(); ++i) {
    const Eigen::Vector2d X = (rest_positions().col(i) - centre) / scale;
    if (fixed_mask_[3 * i + 0]) R.row(r++) << 1.0, 0.0, -X.y();
    if (fixed_mask_[3 * i + 1]) R.row(r++) << 0.0, 1.0, X.x();
    if (fixed_mask_[3 * i + 2]) R.row(r++) << 0.0, 0.0, 1.0;
  }
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(R);
  qr.setThreshold(1e-10);
  return qr.rank() == 3;
}

void BeamModel::evaluate(const Eigen::Ref<const Eigen::VectorXd>& u, double* energy,
                         Eigen::Ref<Eigen::VectorXd>* internal_force,
                         BlockTridiagonal* tangent) const {
  if (energy) *energy = 0.0;
  if (internal_force) internal_force->setZero();
  if (tangent) tangent->set_zero();
  const bool has_prestress = !description_.prestress.empty();
  const BeamPrestress none;
  for (int e = 0; e < num_elements(); ++e) {
    double Ue = 0.0;
    Vector6d pe;
    Matrix6d Ke;
    evaluate_beam_element(references_[e], description_.sections[e],
                          has_prestress ? description_.prestress[e] : none, element_dofs(u, e),
                          energy ? &Ue : nullptr, internal_force ? &pe : nullptr,
                          tangent ? &Ke : nullptr);
    if (energy) *energy += Ue;
    if (internal_force) internal_force->segment<6>(3 * e) += pe;
    if (tangent) tangent->add_element(e, Ke);
  }
}

double BeamModel::energy(const Eigen::Ref<const Eigen::VectorXd>& u) const {
  double U = 0.0;
  evaluate(u, &U, nullptr, nullptr);
  return U;
}

Eigen::VectorXd BeamModel::internal_force(const Eigen::Ref<const Eigen::VectorXd>& u) const {
  Eigen::VectorXd p(num_dofs());
  Eigen::Ref<Eigen::VectorXd> ref(p);
  evaluate(u, nullptr, &ref, nullptr);
  return p;
}

Eigen::Matrix2Xd BeamModel::current_positions(const Eigen::Ref<const Eigen::VectorXd>& u) const {
  Eigen::Matrix2Xd x = rest_positions();
  for (int i = 0; i < num_nodes(); ++i) x.col(i) += u.segment<2>(3 * i);
  return x;
}

}  // namespace sinew::common
