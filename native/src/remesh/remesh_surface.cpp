#include "nfield/remesh/remesh_surface.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numeric>
#include <unordered_map>

#include "nfield/errors.hpp"

namespace nfield::remesh {

namespace {
constexpr double kPi = 3.14159265358979323846;

int find(std::vector<int>& parent, int x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

double corner_angle(const Vec3& a, const Vec3& b, const Vec3& c) {  // at a
  const Vec3 u = b - a, v = c - a;
  return std::atan2(u.cross(v).norm(), u.dot(v));
}
}  // namespace

RemeshSurface make_remesh_surface(const TriangleMesh& mesh) {
  RemeshSurface s;
  const int F = mesh.num_faces();
  const auto& faces = mesh.faces();
  // Union the corners around each vertex that are linked by dual edges.
  std::vector<int> parent(3 * F);
  std::iota(parent.begin(), parent.end(), 0);
  auto slot = [&](int f, int v) {
    for (int c = 0; c < 3; ++c)
      if (faces(f, c) == v) return c;
    return -1;
  };
  for (const DualEdge& e : mesh.dual_edges())
    for (int v : {e.vertex0, e.vertex1}) {
      const int c0 = slot(e.face0, v), c1 = slot(e.face1, v);
      if (c0 < 0 || c1 < 0) continue;
      parent[find(parent, 3 * e.face0 + c0)] = find(parent, 3 * e.face1 + c1);
    }
  std::vector<int> cut_of_root(3 * F, -1);
  for (int f = 0; f < F; ++f) {
    if (!mesh.face_active(f)) continue;
    std::array<int, 3> tri;
    for (int c = 0; c < 3; ++c) {
      const int root = find(parent, 3 * f + c);
      if (cut_of_root[root] < 0) {
        cut_of_root[root] = static_cast<int>(s.positions.size());
        s.positions.push_back(mesh.positions().row(faces(f, c)).transpose());
        s.source_vertex.push_back(faces(f, c));
      }
      tri[c] = cut_of_root[root];
    }
    s.triangles.push_back(tri);
    s.source_triangle.push_back(f);
  }
  if (s.triangles.empty()) throw InputError("the mesh has no usable (non-degenerate) face to remesh");
  finalize_surface(s);
  return s;
}

namespace {

/// refine_long_edges with a limit per vertex when `limit` is given (edge ab long above the mean of its ends'
/// limits; a midpoint takes that mean), else `max_length` everywhere.
void refine_edges(RemeshSurface& s, double max_length, std::vector<double>* limit) {
  const double max2 = max_length * max_length;
  for (int pass = 0; pass < 32; ++pass) {
    std::unordered_map<long long, int> midpoint;
    auto mid = [&](int a, int b) {
      if (a > b) std::swap(a, b);
      const long long key = (static_cast<long long>(a) << 32) | static_cast<unsigned int>(b);
      auto [it, inserted] = midpoint.emplace(key, static_cast<int>(s.positions.size()));
      if (inserted) {
        s.positions.push_back(0.5 * (s.positions[a] + s.positions[b]));
        s.source_vertex.push_back(-1);
        if (limit) limit->push_back(0.5 * ((*limit)[a] + (*limit)[b]));
      }
      return it->second;
    };
    auto is_long = [&](int a, int b) {
      const double d2 = (s.positions[a] - s.positions[b]).squaredNorm();
      if (!limit) return d2 > max2;
      const double m = 0.5 * ((*limit)[a] + (*limit)[b]);
      return d2 > m * m;
    };
    std::vector<std::array<int, 3>> triangles;
    std::vector<int> source;
    bool changed = false;
    const size_t T = s.triangles.size();
    for (size_t t = 0; t < T; ++t) {
      const auto tri = s.triangles[t];
      bool mark[3];
      int count = 0;
      for (int c = 0; c < 3; ++c) count += mark[c] = is_long(tri[c], tri[(c + 1) % 3]);
      auto emit = [&](int a, int b, int c) {
        triangles.push_back({a, b, c});
        source.push_back(s.source_triangle[t]);
      };
      if (count == 0) {
        emit(tri[0], tri[1], tri[2]);
        continue;
      }
      changed = true;
      // Rotate so that edge (r0, r1) is marked; edges are (r0,r1), (r1,r2), (r2,r0).
      int k = 0;
      if (count == 2) {
        while (mark[k] == 0 || mark[(k + 1) % 3] == 0) ++k;  // k and k+1 marked
      } else {
        while (!mark[k]) ++k;
      }
      const int a = tri[k], b = tri[(k + 1) % 3], c = tri[(k + 2) % 3];
      if (count == 1) {
        const int m = mid(a, b);
        emit(a, m, c);
        emit(m, b, c);
      } else if (count == 2) {
        const int m0 = mid(a, b), m1 = mid(b, c);
        emit(m0, b, m1);
        emit(a, m0, m1);
        emit(a, m1, c);
      } else {
        const int m0 = mid(a, b), m1 = mid(b, c), m2 = mid(c, a);
        emit(a, m0, m2);
        emit(m0, b, m1);
        emit(m2, m1, c);
        emit(m0, m1, m2);
      }
    }
    s.triangles = std::move(triangles);
    s.source_triangle = std::move(source);
    if (!changed) break;
  }
  finalize_surface(s);
}

}  // namespace

void refine_long_edges(RemeshSurface& s, double max_length) {
  if (max_length > 0) refine_edges(s, max_length, nullptr);
}

void refine_long_edges(RemeshSurface& s, std::vector<double>& max_length) {
  if (static_cast<int>(max_length.size()) != s.num_vertices())
    throw ParameterError("refine_long_edges: one limit per vertex is needed");
  for (double m : max_length)
    if (!(m > 0)) throw ParameterError("refine_long_edges: the limits must be positive");
  refine_edges(s, 0, &max_length);
}

void finalize_surface(RemeshSurface& s) {
  const int V = s.num_vertices(), T = static_cast<int>(s.triangles.size());
  s.edges.clear();
  s.edge_faces.clear();
  s.num_components = 0;
  s.face_normals.resize(T);
  s.face_areas.resize(T);
  s.vertex_normals.assign(V, Vec3::Zero());
  s.vertex_areas.assign(V, 0.0);
  for (int t = 0; t < T; ++t) {
    const auto& tri = s.triangles[t];
    const Vec3 n = (s.positions[tri[1]] - s.positions[tri[0]]).cross(s.positions[tri[2]] - s.positions[tri[0]]);
    const double len = n.norm();
    s.face_normals[t] = len > 0 ? Vec3(n / len) : Vec3::Zero();
    s.face_areas[t] = 0.5 * len;
    for (int c = 0; c < 3; ++c) {
      const double angle = corner_angle(s.positions[tri[c]], s.positions[tri[(c + 1) % 3]], s.positions[tri[(c + 2) % 3]]);
      s.vertex_normals[tri[c]] += angle * s.face_normals[t];
      s.vertex_areas[tri[c]] += s.face_areas[t] / 3.0;
    }
  }
  for (int v = 0; v < V; ++v) {
    const double len = s.vertex_normals[v].norm();
    if (len > 0) s.vertex_normals[v] /= len;
  }

  // Edges.
  std::unordered_map<long long, int> edge_index;
  for (int t = 0; t < T; ++t)
    for (int c = 0; c < 3; ++c) {
      int a = s.triangles[t][c], b = s.triangles[t][(c + 1) % 3];
      if (a > b) std::swap(a, b);
      const long long key = (static_cast<long long>(a) << 32) | static_cast<unsigned int>(b);
      auto [it, inserted] = edge_index.emplace(key, static_cast<int>(s.edges.size()));
      if (inserted) {
        s.edges.push_back({a, b});
        s.edge_faces.push_back({t, -1});
      } else {
        // A third face on a cut edge cannot happen after the split; keep the first two if it does.
        auto& ef = s.edge_faces[it->second];
        if (ef[1] < 0) ef[1] = t;
      }
    }
  std::vector<int> degree(V, 0);
  for (const auto& e : s.edges) {
    ++degree[e[0]];
    ++degree[e[1]];
  }
  s.adjacency_offsets.assign(V + 1, 0);
  for (int v = 0; v < V; ++v) s.adjacency_offsets[v + 1] = s.adjacency_offsets[v] + degree[v];
  s.adjacency.resize(s.adjacency_offsets[V]);
  s.adjacency_edge.resize(s.adjacency_offsets[V]);
  std::vector<int> fill(s.adjacency_offsets.begin(), s.adjacency_offsets.end() - 1);
  for (int e = 0; e < static_cast<int>(s.edges.size()); ++e) {
    const int a = s.edges[e][0], b = s.edges[e][1];
    s.adjacency[fill[a]] = b;
    s.adjacency_edge[fill[a]++] = e;
    s.adjacency[fill[b]] = a;
    s.adjacency_edge[fill[b]++] = e;
  }

  // Components.
  std::vector<int> comp_parent(V);
  std::iota(comp_parent.begin(), comp_parent.end(), 0);
  for (const auto& e : s.edges) comp_parent[find(comp_parent, e[0])] = find(comp_parent, e[1]);
  s.vertex_component.assign(V, -1);
  std::vector<int> comp_of_root(V, -1);
  for (int v = 0; v < V; ++v) {
    const int r = find(comp_parent, v);
    if (comp_of_root[r] < 0) comp_of_root[r] = s.num_components++;
    s.vertex_component[v] = comp_of_root[r];
  }
  s.component_area.assign(s.num_components, 0.0);
  s.component_triangles.assign(s.num_components, 0);
  std::vector<Vec3> lo(s.num_components, Vec3::Constant(1e300)), hi(s.num_components, Vec3::Constant(-1e300));
  for (int t = 0; t < T; ++t) {
    const int c = s.vertex_component[s.triangles[t][0]];
    s.component_area[c] += s.face_areas[t];
    ++s.component_triangles[c];
  }
  for (int v = 0; v < V; ++v) {
    const int c = s.vertex_component[v];
    lo[c] = lo[c].cwiseMin(s.positions[v]);
    hi[c] = hi[c].cwiseMax(s.positions[v]);
  }
  s.component_diagonal.resize(s.num_components);
  for (int c = 0; c < s.num_components; ++c) s.component_diagonal[c] = (hi[c] - lo[c]).norm();
}

Features detect_features(const RemeshSurface& s, bool keep_boundary, double sharp_angle_degrees,
                         double min_chain_length) {
  Features f;
  const int E = static_cast<int>(s.edges.size());
  f.edge_is_feature.assign(E, 0);
  const double cos_sharp = sharp_angle_degrees > 0 ? std::cos(sharp_angle_degrees * kPi / 180.0) : -2.0;
  for (int e = 0; e < E; ++e) {
    const auto& ef = s.edge_faces[e];
    if (ef[1] < 0) {
      if (keep_boundary) f.edge_is_feature[e] = 1;
    } else if (s.face_normals[ef[0]].dot(s.face_normals[ef[1]]) < cos_sharp) {
      f.edge_is_feature[e] = 1;
    }
  }
  finish_features(s, f, min_chain_length);
  return f;
}

void finish_features(const RemeshSurface& s, Features& f, double min_chain_length) {
  const int E = static_cast<int>(s.edges.size()), V = s.num_vertices();
  // Drop short chains: connected components of the feature-edge graph with a small total length.
  std::vector<int> parent(V);
  std::iota(parent.begin(), parent.end(), 0);
  for (int e = 0; e < E; ++e)
    if (f.edge_is_feature[e]) parent[find(parent, s.edges[e][0])] = find(parent, s.edges[e][1]);
  std::vector<double> chain_length(V, 0.0);
  for (int e = 0; e < E; ++e)
    if (f.edge_is_feature[e])
      chain_length[find(parent, s.edges[e][0])] += (s.positions[s.edges[e][0]] - s.positions[s.edges[e][1]]).norm();
  std::vector<char> counted(V, 0);
  for (int e = 0; e < E; ++e) {
    if (!f.edge_is_feature[e]) continue;
    const int r = find(parent, s.edges[e][0]);
    if (chain_length[r] < min_chain_length) {
      f.edge_is_feature[e] = 0;
      if (!counted[r]) {
        counted[r] = 1;
        ++f.num_dropped_chains;
      }
    }
  }
  f.num_boundary_edges = f.num_sharp_edges = 0;
  for (int e = 0; e < E; ++e)
    if (f.edge_is_feature[e]) (s.edge_faces[e][1] < 0 ? f.num_boundary_edges : f.num_sharp_edges)++;

  // Kinds: two feature edges turning by less than 45 degrees make a curve vertex, and so does the end of a
  // chain (one feature edge: a crease fading out needs no lattice point of its own, only its line); junctions
  // and sharp turns are corners.
  f.vertex_kind.assign(V, kNoFeature);
  f.vertex_tangent.assign(V, Vec3::Zero());
  for (int v = 0; v < V; ++v) {
    int ends[3], count = 0;
    for (int k = s.adjacency_offsets[v]; k < s.adjacency_offsets[v + 1]; ++k)
      if (f.edge_is_feature[s.adjacency_edge[k]]) {
        if (count < 3) ends[count] = s.adjacency[k];
        ++count;
      }
    if (count == 0) continue;
    const Vec3& n = s.vertex_normals[v];
    auto tangent_along = [&](Vec3 t, const Vec3& fallback) {
      t -= n * n.dot(t);
      return t.norm() > 0 ? Vec3(t.normalized()) : fallback;
    };
    if (count == 1) {
      const Vec3 a = (s.positions[ends[0]] - s.positions[v]).normalized();
      f.vertex_kind[v] = kCurve;
      f.vertex_tangent[v] = tangent_along(a, a);
      continue;
    }
    if (count != 2) {
      f.vertex_kind[v] = kCorner;
      continue;
    }
    const Vec3 a = (s.positions[ends[0]] - s.positions[v]).normalized();
    const Vec3 b = (s.positions[v] - s.positions[ends[1]]).normalized();
    if (a.dot(b) < std::cos(kPi / 4)) {
      f.vertex_kind[v] = kCorner;
    } else {
      f.vertex_kind[v] = kCurve;
      f.vertex_tangent[v] = tangent_along(a + b, a);
    }
  }
}

int keep_features_along_field(const RemeshSurface& s, Features& f, const std::vector<Vec3>& triangle_directions,
                              double max_angle_degrees, double min_chain_length) {
  const double max_angle = max_angle_degrees * kPi / 180.0;
  int dropped = 0;
  for (size_t e = 0; e < s.edges.size(); ++e) {
    if (!f.edge_is_feature[e] || s.edge_faces[e][1] < 0) continue;  // boundaries always stay
    const Vec3 d = s.positions[s.edges[e][1]] - s.positions[s.edges[e][0]];
    bool along = true;
    for (int t : s.edge_faces[e]) {
      const Vec3& n = s.face_normals[t];
      const Vec3& q = triangle_directions[t];
      if (q.squaredNorm() == 0 || n.squaredNorm() == 0) continue;  // no field there: nothing to cross
      // angle between the edge and the nearest of the face's four cross directions, in [0, 45] degrees
      double angle = std::fmod(std::abs(std::atan2(d.dot(n.cross(q)), d.dot(q))), kPi / 2);
      angle = std::min(angle, kPi / 2 - angle);
      along = along && angle <= max_angle;
    }
    if (!along) {
      f.edge_is_feature[e] = 0;
      ++dropped;
    }
  }
  if (dropped) finish_features(s, f, min_chain_length);
  return dropped;
}

Vec3 rotate_between_planes(const Vec3& d, const Vec3& from, const Vec3& to) {
  const Vec3 axis = from.cross(to);
  const double s = axis.norm(), c = from.dot(to);
  if (s < 1e-12) {
    // Same plane (or opposite normals): project.
    return d - to * to.dot(d);
  }
  const Vec3 k = axis / s;
  // Rodrigues: d cos + (k x d) sin + k (k.d)(1 - cos)
  return d * c + k.cross(d) * s + k * k.dot(d) * (1 - c);
}

std::vector<Vec3> vertex_cross_field(const RemeshSurface& s, const std::vector<Vec3>& triangle_directions,
                                     const Features* features, int* num_undefined) {
  const int V = s.num_vertices();
  std::vector<std::complex<double>> sum(V, {0.0, 0.0});
  std::vector<double> weight(V, 0.0), best_weight(V, 0.0);
  std::vector<Vec3> best_dir(V, Vec3::Zero());
  std::vector<Vec3> xs(V), ys(V);
  for (int v = 0; v < V; ++v) {
    const Vec3& n = s.vertex_normals[v];
    Vec3 x = n.unitOrthogonal();
    // A frame that does not depend on anything but the normal; any frame works (4th powers are compared
    // in the same frame).
    xs[v] = x;
    ys[v] = n.cross(x);
  }
  for (size_t t = 0; t < s.triangles.size(); ++t) {
    const Vec3& d = triangle_directions[t];
    if (!(d.squaredNorm() > 0) || !d.allFinite()) continue;
    const auto& tri = s.triangles[t];
    for (int c = 0; c < 3; ++c) {
      const int v = tri[c];
      const double w = corner_angle(s.positions[v], s.positions[tri[(c + 1) % 3]], s.positions[tri[(c + 2) % 3]]);
      if (!(w > 0)) continue;
      const Vec3 r = rotate_between_planes(d.normalized(), s.face_normals[t], s.vertex_normals[v]);
      const double a = std::atan2(r.dot(ys[v]), r.dot(xs[v]));
      sum[v] += w * std::polar(1.0, 4 * a);
      weight[v] += w;
      if (w > best_weight[v]) {
        best_weight[v] = w;
        best_dir[v] = r;
      }
    }
  }
  std::vector<Vec3> out(V);
  int undefined = 0;
  for (int v = 0; v < V; ++v) {
    const Vec3& n = s.vertex_normals[v];
    if (features && features->vertex_kind[v] == kCurve) {
      out[v] = features->vertex_tangent[v];
      continue;
    }
    if (weight[v] <= 0) {
      ++undefined;
      Vec3 e = Vec3::UnitX();
      if (s.adjacency_offsets[v + 1] > s.adjacency_offsets[v]) e = s.positions[s.adjacency[s.adjacency_offsets[v]]] - s.positions[v];
      e -= n * n.dot(e);
      out[v] = e.norm() > 0 ? Vec3(e.normalized()) : xs[v];
      continue;
    }
    if (std::abs(sum[v]) > 1e-6 * weight[v]) {
      const double a = std::arg(sum[v]) / 4;
      out[v] = std::cos(a) * xs[v] + std::sin(a) * ys[v];
    } else {
      Vec3 r = best_dir[v] - n * n.dot(best_dir[v]);
      out[v] = r.norm() > 0 ? Vec3(r.normalized()) : xs[v];
    }
  }
  if (num_undefined) *num_undefined = undefined;
  return out;
}

}  // namespace nfield::remesh
