#include "nfield/remesh/polygon_mesh.hpp"

#include <algorithm>
#include <numeric>
#include <string>
#include <unordered_map>

#include "nfield/errors.hpp"

namespace nfield::remesh {

namespace {

inline long long edge_key(int a, int b) { return undirected_edge_key(a, b); }

int find(std::vector<int>& parent, int x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

}  // namespace

std::vector<std::vector<int>> face_lists(const PolygonMesh& m) {
  std::vector<std::vector<int>> f(m.num_faces());
  for (int i = 0; i < m.num_faces(); ++i) f[i].assign(m.face(i), m.face(i) + m.face_size(i));
  return f;
}

void set_faces(PolygonMesh& m, const std::vector<std::vector<int>>& faces) {
  m.offsets.assign(1, 0);
  m.indices.clear();
  for (const auto& f : faces)
    if (!f.empty()) m.add_face(f);
}

std::vector<int> merge_polygons_across(const std::vector<int>& a, const std::vector<int>& b, int u, int v) {
  const int ka = static_cast<int>(a.size()), kb = static_cast<int>(b.size());
  const int ia = static_cast<int>(std::find(a.begin(), a.end(), v) - a.begin());
  const int ib = static_cast<int>(std::find(b.begin(), b.end(), u) - b.begin());
  std::vector<int> out;
  for (int k = 0; k < ka; ++k) out.push_back(a[(ia + k) % ka]);      // v ... u
  for (int k = 1; k < kb - 1; ++k) out.push_back(b[(ib + k) % kb]);  // after u ... before v
  return out;
}

void PolygonMesh::validate() const {
  if (offsets.empty() || offsets.front() != 0 || offsets.back() != static_cast<int>(indices.size()))
    throw InputError("polygon mesh: face offsets do not match the index list");
  for (int f = 0; f < num_faces(); ++f) {
    if (face_size(f) < 3)
      throw InputError("polygon mesh: face " + std::to_string(f) + " has " + std::to_string(face_size(f)) +
                       " vertices (at least 3 needed)");
    for (int k = 0; k < face_size(f); ++k)
      if (face(f)[k] < 0 || face(f)[k] >= num_vertices())
        throw InputError("polygon mesh: face " + std::to_string(f) + " has vertex index " +
                         std::to_string(face(f)[k]) + ", out of range [0, " + std::to_string(num_vertices()) + ")");
  }
  for (const auto& p : positions)
    if (!p.allFinite()) throw InputError("polygon mesh: a vertex position is not finite");
}

std::vector<std::array<int, 2>> unique_edges(const PolygonMesh& mesh) {
  std::unordered_map<long long, int> seen;
  std::vector<std::array<int, 2>> edges;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int k = mesh.face_size(f);
    const int* v = mesh.face(f);
    for (int i = 0; i < k; ++i) {
      const int a = v[i], b = v[(i + 1) % k];
      if (a == b) continue;
      if (seen.emplace(edge_key(a, b), static_cast<int>(edges.size())).second)
        edges.push_back({std::min(a, b), std::max(a, b)});
    }
  }
  return edges;
}

ManifoldReport check_manifold(const PolygonMesh& mesh) {
  ManifoldReport r;
  // Edge uses: count and directed count (a < b counted +1 for a->b, -1 for b->a).
  std::unordered_map<long long, std::array<int, 3>> uses;  // total, forward, backward
  std::vector<std::vector<std::array<int, 2>>> corners(mesh.num_vertices());  // (prev, next) per corner
  std::vector<char> used(mesh.num_vertices(), 0);
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int k = mesh.face_size(f);
    const int* v = mesh.face(f);
    std::vector<int> sorted(v, v + k);
    std::sort(sorted.begin(), sorted.end());
    if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) ++r.faces_with_repeated_vertex;
    for (int i = 0; i < k; ++i) {
      const int a = v[i], b = v[(i + 1) % k];
      used[a] = 1;
      auto& u = uses[edge_key(a, b)];
      ++u[0];
      ++u[a < b ? 1 : 2];
      corners[a].push_back({v[(i + k - 1) % k], b});
    }
  }
  for (const auto& [key, u] : uses) {
    (void)key;
    if (u[0] > 2) ++r.nonmanifold_edges;
    if (u[1] > 1 || u[2] > 1) ++r.inconsistent_edges;
    if (u[0] == 1) ++r.boundary_edges;
  }
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    if (!used[v]) {
      ++r.isolated_vertices;
      continue;
    }
    // The corners around v form one fan iff linking corner (p, n) to the corner whose prev is n gives a
    // single chain. Union corners sharing a neighbour; count components and check each neighbour is
    // shared by at most two corners.
    const auto& c = corners[v];
    const int m = static_cast<int>(c.size());
    std::vector<int> parent(m);
    std::iota(parent.begin(), parent.end(), 0);
    std::unordered_map<int, std::vector<int>> by_neighbour;
    for (int i = 0; i < m; ++i) {
      by_neighbour[c[i][0]].push_back(i);
      by_neighbour[c[i][1]].push_back(i);
    }
    bool bad = false;
    for (const auto& [nb, list] : by_neighbour) {
      (void)nb;
      if (list.size() > 2) bad = true;
      for (size_t j = 1; j < list.size(); ++j) parent[find(parent, static_cast<int>(list[j]))] = find(parent, list[0]);
    }
    int components = 0;
    for (int i = 0; i < m; ++i) components += find(parent, i) == i;
    if (bad || components > 1) ++r.nonmanifold_vertices;
  }
  return r;
}

int remove_conflicting_faces(PolygonMesh& mesh) {
  std::unordered_map<long long, std::array<int, 3>> uses;
  PolygonMesh out;
  out.positions = mesh.positions;
  int removed = 0;
  std::vector<int> face;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int k = mesh.face_size(f);
    const int* v = mesh.face(f);
    face.assign(v, v + k);
    std::vector<int> sorted = face;
    std::sort(sorted.begin(), sorted.end());
    bool ok = k >= 3 && std::adjacent_find(sorted.begin(), sorted.end()) == sorted.end();
    for (int i = 0; ok && i < k; ++i) {
      const int a = v[i], b = v[(i + 1) % k];
      auto it = uses.find(edge_key(a, b));
      if (it == uses.end()) continue;
      const auto& u = it->second;
      if (u[0] >= 2 || u[a < b ? 1 : 2] >= 1) ok = false;
    }
    if (!ok) {
      ++removed;
      continue;
    }
    for (int i = 0; i < k; ++i) {
      const int a = v[i], b = v[(i + 1) % k];
      auto& u = uses[edge_key(a, b)];
      ++u[0];
      ++u[a < b ? 1 : 2];
    }
    out.add_face(face);
  }
  mesh = std::move(out);
  return removed;
}

int split_pinched_vertices(PolygonMesh& mesh, std::vector<int>* copied_from) {
  // Corners per vertex: (face, position in face, prev, next).
  struct Corner {
    int face, slot, prev, next;
  };
  std::vector<std::vector<Corner>> corners(mesh.num_vertices());
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int k = mesh.face_size(f);
    const int* v = mesh.face(f);
    for (int i = 0; i < k; ++i) corners[v[i]].push_back({f, i, v[(i + k - 1) % k], v[(i + 1) % k]});
  }
  if (copied_from) {
    copied_from->resize(mesh.num_vertices());
    std::iota(copied_from->begin(), copied_from->end(), 0);
  }
  int added = 0;
  const int V = mesh.num_vertices();
  for (int v = 0; v < V; ++v) {
    const auto& c = corners[v];
    const int m = static_cast<int>(c.size());
    if (m <= 1) continue;
    std::vector<int> parent(m);
    std::iota(parent.begin(), parent.end(), 0);
    std::unordered_map<int, int> first_with;
    for (int i = 0; i < m; ++i)
      for (int nb : {c[i].prev, c[i].next}) {
        auto [it, inserted] = first_with.emplace(nb, i);
        if (!inserted) parent[find(parent, i)] = find(parent, it->second);
      }
    std::unordered_map<int, int> copy_of_root;
    for (int i = 0; i < m; ++i) {
      const int root = find(parent, i);
      if (root == find(parent, 0)) continue;
      auto it = copy_of_root.find(root);
      int nv;
      if (it == copy_of_root.end()) {
        nv = mesh.num_vertices();
        mesh.positions.push_back(mesh.positions[v]);
        if (copied_from) copied_from->push_back(v);
        copy_of_root.emplace(root, nv);
        ++added;
      } else {
        nv = it->second;
      }
      mesh.indices[mesh.offsets[c[i].face] + c[i].slot] = nv;
    }
  }
  return added;
}

int collapse_short_edges(PolygonMesh& mesh, double min_length, std::vector<int>* merged_into) {
  const int V = mesh.num_vertices();
  std::vector<int> parent(V);
  std::iota(parent.begin(), parent.end(), 0);
  int merged = 0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int k = mesh.face_size(f);
    const int* v = mesh.face(f);
    for (int i = 0; i < k; ++i) {
      const int a = find(parent, v[i]), b = find(parent, v[(i + 1) % k]);
      if (a != b && (mesh.positions[a] - mesh.positions[b]).norm() < min_length) {
        parent[std::max(a, b)] = std::min(a, b);
        ++merged;
      }
    }
  }
  if (merged_into) {
    merged_into->resize(V);
    for (int v = 0; v < V; ++v) (*merged_into)[v] = find(parent, v);
  }
  if (merged == 0) return 0;
  PolygonMesh out;
  out.positions = mesh.positions;
  std::vector<int> face;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    face.clear();
    for (int i = 0; i < mesh.face_size(f); ++i) {
      const int r = find(parent, mesh.face(f)[i]);
      if (face.empty() || face.back() != r) face.push_back(r);
    }
    while (face.size() > 1 && face.front() == face.back()) face.pop_back();
    if (face.size() >= 3) out.add_face(face);
  }
  mesh = std::move(out);
  remove_conflicting_faces(mesh);
  std::vector<int> copied_from;
  split_pinched_vertices(mesh, &copied_from);
  if (merged_into)
    for (size_t v = V; v < copied_from.size(); ++v) merged_into->push_back((*merged_into)[copied_from[v]]);
  return merged;
}

int remove_small_pieces(PolygonMesh& mesh, int min_faces) {
  std::vector<int> piece(mesh.num_vertices());
  std::iota(piece.begin(), piece.end(), 0);
  for (int f = 0; f < mesh.num_faces(); ++f)
    for (int i = 1; i < mesh.face_size(f); ++i) piece[find(piece, mesh.face(f)[i])] = find(piece, mesh.face(f)[0]);
  std::vector<int> faces_in(mesh.num_vertices(), 0);
  for (int f = 0; f < mesh.num_faces(); ++f) ++faces_in[find(piece, mesh.face(f)[0])];
  PolygonMesh kept;
  kept.positions = mesh.positions;
  int removed = 0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    if (faces_in[find(piece, mesh.face(f)[0])] < min_faces) {
      ++removed;
      continue;
    }
    kept.add_face(std::vector<int>(mesh.face(f), mesh.face(f) + mesh.face_size(f)));
  }
  if (removed) mesh = std::move(kept);
  return removed;
}

std::vector<int> compact_vertices(PolygonMesh& mesh) {
  std::vector<int> new_index(mesh.num_vertices(), -1), old_index;
  for (int& i : mesh.indices) {
    if (new_index[i] < 0) {
      new_index[i] = static_cast<int>(old_index.size());
      old_index.push_back(i);
    }
    i = new_index[i];
  }
  std::vector<Eigen::Vector3d> positions(old_index.size());
  for (size_t i = 0; i < old_index.size(); ++i) positions[i] = mesh.positions[old_index[i]];
  mesh.positions = std::move(positions);
  return old_index;
}

PolygonMesh subdivide_to_quads(const PolygonMesh& mesh, std::vector<int>* kind,
                               std::vector<std::array<int, 2>>* edge_of) {
  PolygonMesh out;
  out.positions = mesh.positions;
  if (kind) kind->assign(mesh.num_vertices(), 0);
  if (edge_of) edge_of->assign(mesh.num_vertices(), {-1, -1});
  std::unordered_map<long long, int> midpoint;
  auto mid = [&](int a, int b) {
    auto [it, inserted] = midpoint.emplace(edge_key(a, b), out.num_vertices());
    if (inserted) {
      out.positions.push_back(0.5 * (mesh.positions[a] + mesh.positions[b]));
      if (kind) kind->push_back(1);
      if (edge_of) edge_of->push_back({std::min(a, b), std::max(a, b)});
    }
    return it->second;
  };
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int k = mesh.face_size(f);
    const int* v = mesh.face(f);
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int i = 0; i < k; ++i) c += mesh.positions[v[i]];
    const int centre = out.num_vertices();
    out.positions.push_back(c / k);
    if (kind) kind->push_back(2);
    if (edge_of) edge_of->push_back({-1, -1});
    for (int i = 0; i < k; ++i) {
      const int prev = v[(i + k - 1) % k], cur = v[i], next = v[(i + 1) % k];
      out.add_face({cur, mid(cur, next), centre, mid(prev, cur)});
    }
  }
  return out;
}

std::vector<std::array<int, 3>> fan_triangulate(const PolygonMesh& mesh, std::vector<int>* triangle_face) {
  std::vector<std::array<int, 3>> tris;
  if (triangle_face) triangle_face->clear();
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int k = mesh.face_size(f);
    const int* v = mesh.face(f);
    for (int i = 1; i + 1 < k; ++i) {
      tris.push_back({v[0], v[i], v[i + 1]});
      if (triangle_face) triangle_face->push_back(f);
    }
  }
  return tris;
}

Eigen::Vector3d polygon_centroid(const PolygonMesh& mesh, int f) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (int i = 0; i < mesh.face_size(f); ++i) c += mesh.positions[mesh.face(f)[i]];
  return c / mesh.face_size(f);
}

Eigen::Vector3d polygon_normal(const PolygonMesh& mesh, int f) {
  return polygon_normal(mesh.positions, std::vector<int>(mesh.face(f), mesh.face(f) + mesh.face_size(f)));
}

Eigen::Vector3d polygon_normal(const std::vector<Eigen::Vector3d>& positions, const std::vector<int>& polygon) {
  const size_t k = polygon.size();
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < k; ++i) n += positions[polygon[i]].cross(positions[polygon[(i + 1) % k]]);
  const double len = n.norm();
  return len > 0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}

std::unordered_map<long long, int> directed_face_map(const std::vector<std::vector<int>>& faces) {
  std::unordered_map<long long, int> d;
  for (int f = 0; f < static_cast<int>(faces.size()); ++f) {
    const auto& p = faces[f];
    for (size_t i = 0; i < p.size(); ++i)
      d[(static_cast<long long>(p[i]) << 32) | static_cast<unsigned int>(p[(i + 1) % p.size()])] = f;
  }
  return d;
}

}  // namespace nfield::remesh
