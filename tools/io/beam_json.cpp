#include "tools/io/beam_json.hpp"

namespace sinew::tools {

namespace {
int node_index(const JsonCursor& c, int num_nodes) {
  const long i = c.integer();
  if (i < 0 || i >= num_nodes) {
    c.fail("= " + std::to_string(i) + " is out of range (the beam has " +
           std::to_string(num_nodes) + " nodes, 0.." + std::to_string(num_nodes - 1) + ")");
  }
  return static_cast<int>(i);
}
}  // namespace

common::BeamDescription parse_beam_description(const JsonCursor& root) {
  const JsonCursor nodes = root.at("nodes");
  const std::size_t n = nodes.array_size();
  if (n < 2) nodes.fail("must hold at least 2 nodes, got " + std::to_string(n));
  Eigen::Matrix2Xd X(2, n);
  for (std::size_t i = 0; i < n; ++i) {
    const JsonCursor node = nodes.at(i);
    if (node.array_size() != 2) node.fail("must be [x, y]");
    X(0, i) = node.at(std::size_t{0}).finite_number();
    X(1, i) = node.at(std::size_t{1}).finite_number();
  }

  const JsonCursor material = root.at("material");
  material.expect_keys({"E", "G", "A", "I"});
  common::BeamMaterial m;
  m.E = material.at("E").positive_number();
  m.G = material.at("G").positive_number();
  m.A = material.at("A").positive_number();
  m.I = material.at("I").positive_number();

  common::BeamDescription d = common::BeamDescription::uniform(X, m);
  if (root.has("fixed")) {
    const JsonCursor fixed = root.at("fixed");
    for (std::size_t k = 0; k < fixed.array_size(); ++k) {
      const JsonCursor entry = fixed.at(k);
      entry.expect_keys({"node", "dofs"});
      const int node = node_index(entry.at("node"), static_cast<int>(n));
      const JsonCursor dofs = entry.at("dofs");
      if (dofs.array_size() == 0) dofs.fail("is empty (name at least one of ux, uy, theta)");
      for (std::size_t j = 0; j < dofs.array_size(); ++j) {
        const std::string name = dofs.at(j).string();
        if (name == "ux") {
          d.fix(node, common::BeamDof::kUx);
        } else if (name == "uy") {
          d.fix(node, common::BeamDof::kUy);
        } else if (name == "theta") {
          d.fix(node, common::BeamDof::kTheta);
        } else {
          dofs.at(j).fail("= \"" + name + "\" is not a dof (ux, uy or theta)");
        }
      }
    }
  }
  if (auto err = d.validate()) throw InputError(root.file() + ": " + *err);
  return d;
}

Eigen::VectorXd parse_beam_loads(const JsonCursor& root, int num_nodes) {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * num_nodes);
  if (!root.has("loads")) return f;
  const JsonCursor loads = root.at("loads");
  for (std::size_t k = 0; k < loads.array_size(); ++k) {
    const JsonCursor entry = loads.at(k);
    entry.expect_keys({"node", "f"});
    const int node = node_index(entry.at("node"), num_nodes);
    const JsonCursor value = entry.at("f");
    if (value.array_size() != 3) value.fail("must be [fx, fy, m]");
    for (std::size_t j = 0; j < 3; ++j) f[3 * node + j] += value.at(j).finite_number();
  }
  return f;
}

nlohmann::json beam_state_to_json(const common::BeamModel& model,
                                  const Eigen::Ref<const Eigen::VectorXd>& u) {
  nlohmann::json nodes = nlohmann::json::array();
  const Eigen::Matrix2Xd x = model.current_positions(u);
  for (int i = 0; i < model.num_nodes(); ++i) {
    nodes.push_back({x(0, i), x(1, i), u[3 * i + 2]});
  }
  return nodes;
}

}  // namespace sinew::tools
