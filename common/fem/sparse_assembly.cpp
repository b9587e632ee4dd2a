#include "common/fem/sparse_assembly.hpp"

#include <algorithm>
#include <cassert>

namespace sinew::common {

const char* to_string(AssemblyStatus status) {
  switch (status) {
    case AssemblyStatus::kOk:
      return "ok";
    case AssemblyStatus::kNotAnalysed:
      return "pattern not analysed";
    case AssemblyStatus::kInvalidDimensions:
      return "invalid dimensions";
    case AssemblyStatus::kIndexOutOfRange:
      return "vertex index out of range";
  }
  return "unknown";
}

Eigen::VectorXd to_dof_vector(const Eigen::Ref<const Eigen::MatrixXd>& positions) {
  Eigen::VectorXd dofs(positions.size());
  for (Eigen::Index v = 0; v < positions.rows(); ++v) {
    for (Eigen::Index d = 0; d < positions.cols(); ++d)
      dofs[positions.cols() * v + d] = positions(v, d);
  }
  return dofs;
}

Eigen::MatrixXd to_positions(const Eigen::Ref<const Eigen::VectorXd>& dofs) {
  const Eigen::Index n = dofs.size() / 3;
  Eigen::MatrixXd positions(n, 3);
  for (Eigen::Index v = 0; v < n; ++v) positions.row(v) = dofs.segment<3>(3 * v).transpose();
  return positions;
}

AssemblyStatus SparseAssembly::analyse(const Eigen::Ref<const Eigen::MatrixXi>& elements,
                                       Eigen::Index num_vertices, PatternStorage storage) {
  *this = SparseAssembly();
  if (num_vertices < 0 || elements.cols() < 1) {
    status_ = AssemblyStatus::kInvalidDimensions;
    return status_;
  }
  for (Eigen::Index e = 0; e < elements.rows(); ++e) {
    for (Eigen::Index a = 0; a < elements.cols(); ++a) {
      if (elements(e, a) < 0 || elements(e, a) >= num_vertices) {
        status_ = AssemblyStatus::kIndexOutOfRange;
        bad_element_ = e;
        return status_;
      }
    }
  }

  // Vertex adjacency (sorted, unique; a vertex is its own neighbour): the block pattern.
  std::vector<std::vector<int>> neighbours(static_cast<std::size_t>(num_vertices));
  for (Eigen::Index e = 0; e < elements.rows(); ++e) {
    for (Eigen::Index a = 0; a < elements.cols(); ++a) {
      for (Eigen::Index b = 0; b < elements.cols(); ++b) {
        neighbours[static_cast<std::size_t>(elements(e, b))].push_back(elements(e, a));
      }
    }
  }
  for (std::vector<int>& list : neighbours) {
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
  }

  // Compressed column-major arrays, built directly so inner indices are sorted by construction.
  const Eigen::Index n = kDofsPerVertex * num_vertices;
  std::vector<StorageIndex> outer(static_cast<std::size_t>(n) + 1, 0);
  std::vector<StorageIndex> inner;
  for (Eigen::Index v = 0; v < num_vertices; ++v) {
    for (int d = 0; d < kDofsPerVertex; ++d) {
      const Eigen::Index col = kDofsPerVertex * v + d;
      for (const int u : neighbours[static_cast<std::size_t>(v)]) {
        for (int r = 0; r < kDofsPerVertex; ++r) {
          const Eigen::Index row = kDofsPerVertex * u + r;
          if (storage == PatternStorage::kUpper && row > col) continue;
          inner.push_back(static_cast<StorageIndex>(row));
        }
      }
      outer[static_cast<std::size_t>(col) + 1] = static_cast<StorageIndex>(inner.size());
    }
  }
  std::vector<double> values(inner.size(), 0.0);
  matrix_ = Eigen::Map<const Eigen::SparseMatrix<double>>(
      n, n, static_cast<Eigen::Index>(inner.size()), outer.data(), inner.data(), values.data());
  matrix_.makeCompressed();

  // Scatter map: binary search once here, never again.
  const int k = static_cast<int>(elements.cols());
  const int m = kDofsPerVertex * k;
  scatter_.assign(static_cast<std::size_t>(elements.rows()) * m * m, kNotStored);
  const StorageIndex* outer_ptr = matrix_.outerIndexPtr();
  const StorageIndex* inner_ptr = matrix_.innerIndexPtr();
  for (Eigen::Index e = 0; e < elements.rows(); ++e) {
    StorageIndex* map = scatter_.data() + static_cast<std::size_t>(e) * m * m;
    for (int c = 0; c < m; ++c) {
      const StorageIndex col = static_cast<StorageIndex>(
          kDofsPerVertex * elements(e, c / kDofsPerVertex) + c % kDofsPerVertex);
      const StorageIndex* begin = inner_ptr + outer_ptr[col];
      const StorageIndex* end = inner_ptr + outer_ptr[col + 1];
      for (int r = 0; r < m; ++r) {
        const StorageIndex row = static_cast<StorageIndex>(
            kDofsPerVertex * elements(e, r / kDofsPerVertex) + r % kDofsPerVertex);
        if (storage == PatternStorage::kUpper && row > col) continue;
        const StorageIndex* it = std::lower_bound(begin, end, row);
        assert(it != end && *it == row);
        map[r + m * c] = static_cast<StorageIndex>(it - inner_ptr);
      }
    }
  }

  elements_ = elements;
  num_vertices_ = num_vertices;
  storage_ = storage;
  status_ = AssemblyStatus::kOk;
  return status_;
}

void SparseAssembly::set_zero() {
  std::fill_n(matrix_.valuePtr(), matrix_.nonZeros(), 0.0);
}

void SparseAssembly::add_element_matrix(Eigen::Index e,
                                        const Eigen::Ref<const Eigen::MatrixXd>& element_matrix) {
  const int m = element_dofs();
  assert(status_ == AssemblyStatus::kOk);
  assert(e >= 0 && e < num_elements());
  assert(element_matrix.rows() == m && element_matrix.cols() == m);
  const StorageIndex* map = scatter_.data() + static_cast<std::size_t>(e) * m * m;
  double* values = matrix_.valuePtr();
  for (int c = 0; c < m; ++c) {
    for (int r = 0; r < m; ++r) {
      const StorageIndex index = map[r + m * c];
      if (index != kNotStored) values[index] += element_matrix(r, c);
    }
  }
}

AssemblyStatus SparseAssembly::assemble(const Eigen::Ref<const Eigen::MatrixXd>& element_matrices) {
  if (status_ != AssemblyStatus::kOk) return AssemblyStatus::kNotAnalysed;
  const int m = element_dofs();
  if (element_matrices.rows() != m || element_matrices.cols() != m * num_elements()) {
    return AssemblyStatus::kInvalidDimensions;
  }
  set_zero();
  for (Eigen::Index e = 0; e < num_elements(); ++e) {
    add_element_matrix(e, element_matrices.middleCols(m * e, m));
  }
  return AssemblyStatus::kOk;
}

void SparseAssembly::add_element_vector(Eigen::Index e,
                                        const Eigen::Ref<const Eigen::VectorXd>& element_vector,
                                        Eigen::Ref<Eigen::VectorXd> global) const {
  assert(status_ == AssemblyStatus::kOk);
  assert(element_vector.size() == element_dofs() && global.size() == num_dofs());
  for (int a = 0; a < vertices_per_element(); ++a) {
    global.segment<kDofsPerVertex>(kDofsPerVertex * elements_(e, a)) +=
        element_vector.segment<kDofsPerVertex>(kDofsPerVertex * a);
  }
}

AssemblyStatus SparseAssembly::assemble_vector(
    const Eigen::Ref<const Eigen::MatrixXd>& element_vectors,
    Eigen::Ref<Eigen::VectorXd> global) const {
  if (status_ != AssemblyStatus::kOk) return AssemblyStatus::kNotAnalysed;
  if (element_vectors.rows() != element_dofs() || element_vectors.cols() != num_elements() ||
      global.size() != num_dofs()) {
    return AssemblyStatus::kInvalidDimensions;
  }
  global.setZero();
  for (Eigen::Index e = 0; e < num_elements(); ++e) {
    add_element_vector(e, element_vectors.col(e), global);
  }
  return AssemblyStatus::kOk;
}

}  // namespace sinew::common
