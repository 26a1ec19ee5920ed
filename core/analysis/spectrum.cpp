// SPDX-License-Identifier: MIT
// Copyright (c) 2026 stlrefine authors
#include "core/analysis/spectrum.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

#include "core/error.h"

namespace stlrefine::analysis {

namespace {

using cd = std::complex<double>;

cd omega(int n, int power) {
  const double t = 2 * std::numbers::pi * power / n;
  return {std::cos(t), std::sin(t)};
}

// Geometric multiplicity of `value` in b: the dimension of the null space of b - value I.
int null_dimension(const Eigen::MatrixXcd& b, cd value) {
  const Eigen::Index size = b.rows();
  Eigen::MatrixXcd shifted = b - value * Eigen::MatrixXcd::Identity(size, size);
  Eigen::JacobiSVD<Eigen::MatrixXcd> svd(shifted);
  const double scale = std::max(1.0, b.cwiseAbs().maxCoeff());
  int zero = 0;
  for (Eigen::Index i = 0; i < svd.singularValues().size(); ++i)
    if (svd.singularValues()[i] <= 1e-8 * scale) ++zero;
  return std::max(zero, 1);
}

// Roots of b grouped into clusters (single linkage within tol); each cluster's mean.
std::vector<Eigenvalue> clustered(const Eigen::MatrixXcd& b, int frequency, int copies,
                                  double tol) {
  Eigen::ComplexEigenSolver<Eigen::MatrixXcd> solver(b, false);
  const Eigen::VectorXcd roots = solver.eigenvalues();
  const int count = static_cast<int>(roots.size());
  std::vector<int> parent(count);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (int i = 0; i < count; ++i)
    for (int j = i + 1; j < count; ++j)
      if (std::abs(roots[i] - roots[j]) < tol) parent[find(i)] = find(j);
  std::vector<Eigenvalue> out;
  for (int i = 0; i < count; ++i) {
    if (find(i) != i) continue;
    cd sum = 0;
    int size = 0;
    for (int j = 0; j < count; ++j)
      if (find(j) == i) sum += roots[j], ++size;
    Eigenvalue e;
    e.value = sum / double(size);
    // A real matrix block (f = 0, f = n/2) has real or conjugate roots: snap the noise.
    if (std::abs(e.value.imag()) < 1e-12) e.value = {e.value.real(), 0.0};
    if (std::abs(e.value) < 1e-14) e.value = 0;
    e.frequency = frequency;
    e.algebraic = size * copies;
    e.geometric = std::min(null_dimension(b, e.value), size) * copies;
    out.push_back(e);
  }
  return out;
}

void sort_by_modulus(std::vector<Eigenvalue>& values) {
  std::stable_sort(values.begin(), values.end(), [](const Eigenvalue& x, const Eigenvalue& y) {
    if (std::abs(x.modulus() - y.modulus()) > 1e-9) return x.modulus() > y.modulus();
    if (x.frequency != y.frequency) return x.frequency < y.frequency;
    return x.value.real() > y.value.real();
  });
}

}  // namespace

Eigen::MatrixXcd fourier_block(const LocalMatrix& a, int f) {
  const PolarLayout& lay = a.layout;
  const int n = lay.valence, m = lay.positions();
  const int off = f == 0 ? 1 : 0;
  Eigen::MatrixXcd b = Eigen::MatrixXcd::Zero(m + off, m + off);
  if (f == 0) {
    b(0, 0) = a.a(0, 0);
    for (int p = 0; p < m; ++p) b(1 + p, 0) = a.a(lay.index(p, 0), 0);
    for (int q = 0; q < m; ++q)
      for (int k = 0; k < n; ++k) b(0, 1 + q) += a.a(0, lay.index(q, k));
  }
  for (int p = 0; p < m; ++p)
    for (int q = 0; q < m; ++q)
      for (int k = 0; k < n; ++k)
        b(off + p, off + q) += a.a(lay.index(p, 0), lay.index(q, k)) * omega(n, f * k);
  return b;
}

std::vector<Eigenvalue> spectrum(const LocalMatrix& a, double cluster_tol) {
  const int n = a.layout.valence;
  std::vector<Eigenvalue> out;
  for (int f = 0; 2 * f <= n; ++f) {
    const int copies = (f == 0 || 2 * f == n) ? 1 : 2;
    for (const Eigenvalue& e : clustered(fourier_block(a, f), f, copies, cluster_tol))
      out.push_back(e);
  }
  sort_by_modulus(out);
  return out;
}

std::vector<Eigenvalue> spectrum(const Eigen::MatrixXd& a, double cluster_tol) {
  std::vector<Eigenvalue> out = clustered(a.cast<cd>(), 0, 1, cluster_tol);
  sort_by_modulus(out);
  return out;
}

Eigen::VectorXcd block_eigenvector(const LocalMatrix& a, int f, cd value) {
  const Eigen::MatrixXcd b = fourier_block(a, f);
  Eigen::MatrixXcd shifted = b - value * Eigen::MatrixXcd::Identity(b.rows(), b.cols());
  Eigen::JacobiSVD<Eigen::MatrixXcd> svd(shifted, Eigen::ComputeFullV);
  Eigen::VectorXcd v = svd.matrixV().col(b.cols() - 1);
  return v / v.norm();
}

namespace {

// Signed area of (p, q, r) in the plane.
double area2(const std::array<double, 2>& p, const std::array<double, 2>& q,
             const std::array<double, 2>& r) {
  return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]);
}

// c lies on segment ab, given that the three are collinear.
bool within(const std::array<double, 2>& a, const std::array<double, 2>& b,
            const std::array<double, 2>& c) {
  return std::min(a[0], b[0]) <= c[0] && c[0] <= std::max(a[0], b[0]) &&
         std::min(a[1], b[1]) <= c[1] && c[1] <= std::max(a[1], b[1]);
}

// Closed segments ab and cd share a point (crossing, touching or overlapping).
bool segments_meet(const std::array<double, 2>& a, const std::array<double, 2>& b,
                   const std::array<double, 2>& c, const std::array<double, 2>& d) {
  const double d1 = area2(a, b, c), d2 = area2(a, b, d);
  const double d3 = area2(c, d, a), d4 = area2(c, d, b);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0)))
    return true;
  return (d1 == 0 && within(a, b, c)) || (d2 == 0 && within(a, b, d)) ||
         (d3 == 0 && within(c, d, a)) || (d4 == 0 && within(c, d, b));
}

bool simple_polygon(const std::vector<std::array<double, 2>>& poly) {
  const std::size_t count = poly.size();
  for (std::size_t i = 0; i < count; ++i) {
    for (std::size_t j = i + 2; j < count; ++j) {
      if (i == 0 && j + 1 == count) continue;  // adjacent through the closing segment
      if (segments_meet(poly[i], poly[(i + 1) % count], poly[j], poly[(j + 1) % count]))
        return false;
    }
  }
  return true;
}

}  // namespace

CharacteristicMapCheck check_characteristic_map(const Refiner& refine, const LocalMatrix& a,
                                                const Eigen::VectorXcd& x, int f, int levels) {
  const PolarLayout& lay = a.layout;
  const int n = lay.valence, s = a.scale;
  constexpr double kEps = 1.0 / (1 << 30);  // linearised values in z, as in the matrix
  CharacteristicMapCheck out;
  out.levels = levels;
  // Outside the analysed rings the net is unknown: two runs with different outside data
  // agree exactly where the refined net is determined by the rings alone.
  NetLevel net = make_net_level(n, lay.rings, 2);
  auto refined_values = [&](bool imaginary, double outside) {
    Level level = net.level;
    BigVector<Vec3>& pos = level.mesh.mutable_positions();
    for (std::uint32_t v = 0; v < pos.size(); ++v) pos[v].z = outside * probe_value(VertexId(v));
    pos[net.ids[0].idx].z = 0;
    for (int q = 0; q < lay.positions(); ++q) {
      for (int k = 0; k < n; ++k) {
        const cd v = x[q] * omega(n, f * k);
        pos[net.ids[lay.index(q, k)].idx].z = kEps * (imaginary ? v.imag() : v.real());
      }
    }
    for (int l = 0; l < levels; ++l) level = refine(level);
    return level;
  };
  const Level re = refined_values(false, 0), im = refined_values(true, 0);
  const Level re2 = refined_values(false, 1), im2 = refined_values(true, 1);
  int scale = 1;
  for (int l = 0; l < levels; ++l) scale *= s;
  const int walk = lay.rings * scale;
  const std::vector<VertexId> ids = fine_polar_ids(re.mesh, walk);
  const PolarLayout fine{n, walk};
  auto determined = [&](VertexId v) {
    return re.mesh.position(v).z == re2.mesh.position(v).z &&
           im.mesh.position(v).z == im2.mesh.position(v).z;
  };
  int rho = 0;
  for (int r = 1; r <= walk; ++r) {
    bool all = true;
    for (int b = 0; b < r && all; ++b)
      for (int k = 0; k < n && all; ++k)
        all = determined(ids[fine.index(PolarLayout::position(r - b, b), k)]);
    if (!all) break;
    rho = r;
  }
  rho -= rho % s;
  if (rho < s) return out;  // nothing determined beyond the centre: cannot check
  out.checked = true;
  out.inner_ring = rho / s;
  out.outer_ring = rho;
  // The map at lattice point (k, a, b) of the finest net.
  auto at = [&](int k, int a_, int b_) -> std::array<double, 2> {
    VertexId v;
    if (a_ == 0 && b_ == 0)
      v = ids[0];
    else if (a_ == 0)
      v = ids[fine.index(PolarLayout::position(b_, 0), k + 1)];
    else
      v = ids[fine.index(PolarLayout::position(a_, b_), k)];
    return {re.mesh.position(v).z / kEps, im.mesh.position(v).z / kEps};
  };
  std::vector<double> areas;
  for (int k = 0; k < n; ++k) {
    for (int t = out.inner_ring + 1; t <= rho; ++t) {
      for (int a_ = 0; a_ < t; ++a_) {  // up triangles between rings t - 1 and t
        const int b_ = t - 1 - a_;
        areas.push_back(area2(at(k, a_, b_), at(k, a_ + 1, b_), at(k, a_, b_ + 1)));
      }
      for (int a_ = 0; a_ + 1 < t; ++a_) {  // down triangles
        const int b_ = t - 2 - a_;
        areas.push_back(area2(at(k, a_ + 1, b_), at(k, a_ + 1, b_ + 1), at(k, a_, b_ + 1)));
      }
    }
  }
  const double mean = std::accumulate(areas.begin(), areas.end(), 0.0) / double(areas.size());
  const double smallest = *std::min_element(areas.begin(), areas.end());
  out.min_area_ratio = mean != 0 ? smallest / std::abs(mean) : 0;
  out.regular = mean > 0 && smallest > 0;
  auto ring_polygon = [&](int r) {
    std::vector<std::array<double, 2>> poly;
    for (int k = 0; k < n; ++k)
      for (int b_ = 0; b_ < r; ++b_) poly.push_back(at(k, r - b_, b_));
    return poly;
  };
  out.injective = out.regular && simple_polygon(ring_polygon(out.inner_ring)) &&
                  simple_polygon(ring_polygon(rho));
  return out;
}

SpectralSummary summarize(const Refiner& refine, const LocalMatrix& a, int map_levels) {
  SpectralSummary s;
  s.values = spectrum(a);
  const std::vector<Eigenvalue>& v = s.values;
  constexpr double kTol = 1e-8;
  const bool dominant_simple = !v.empty() && std::abs(v[0].value - 1.0) < kTol &&
                               v[0].algebraic == 1 && (v.size() < 2 || v[1].modulus() < 1 - kTol);
  std::size_t first = v.empty() ? 0 : 1;
  if (!v.empty() && v[0].algebraic > 1) first = 0;  // 1 is not simple: lambda is 1
  if (first < v.size()) s.lambda = v[first].modulus();
  for (std::size_t i = first; i < v.size(); ++i) {
    if (std::abs(v[i].modulus() - s.lambda) < kTol) {
      s.lambda_frequencies.push_back(v[i].frequency);
      s.lambda_multiplicity += v[i].algebraic;
    } else if (v[i].modulus() < s.lambda) {
      s.next = std::max(s.next, v[i].modulus());
    }
  }
  const Eigenvalue* f1 = nullptr;
  for (const Eigenvalue& e : v)
    if (e.frequency == 1 && (!f1 || e.modulus() > f1->modulus() + kTol)) f1 = &e;
  if (f1) s.frequency1 = f1->value;
  const bool lambda_pair = f1 && s.lambda_frequencies == std::vector<int>{1} &&
                           s.lambda_multiplicity == 2 && f1->geometric == 2 &&
                           std::abs(f1->value.imag()) < kTol && f1->value.real() > 0;
  if (f1 && map_levels > 0 && std::abs(f1->value.imag()) < kTol)
    s.characteristic_map =
        check_characteristic_map(refine, a, block_eigenvector(a, 1, f1->value), 1, map_levels);
  s.c1 = dominant_simple && lambda_pair && s.characteristic_map.injective;
  s.c1_jordan = dominant_simple && f1 && !lambda_pair &&
                s.lambda_frequencies == std::vector<int>{1} && f1->geometric == 2 &&
                std::abs(f1->value.imag()) < kTol && f1->value.real() > 0 &&
                s.characteristic_map.injective;
  const double l2 = s.lambda * s.lambda;
  bool below = true;
  for (std::size_t i = first; i < v.size(); ++i) {
    const Eigenvalue& e = v[i];
    if (std::abs(e.modulus() - s.lambda) < kTol && e.frequency == 1) continue;
    const bool quadratic =
        std::abs(e.value - l2) < kTol && (e.frequency == 0 || e.frequency == 2) && !e.jordan();
    if (e.modulus() >= l2 - kTol && !quadratic) below = false;
  }
  s.g2_eigenvalues = s.c1 && below;
  return s;
}

}  // namespace stlrefine::analysis
