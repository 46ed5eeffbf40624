#include "nfield/mesh_cuts.hpp"

#include <algorithm>
#include <map>
#include <numeric>

#include "nfield/errors.hpp"

namespace nfield {
namespace {

class Classes {
 public:
  explicit Classes(int n) : parent_(static_cast<std::size_t>(n)) { std::iota(parent_.begin(), parent_.end(), 0); }
  int find(int x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }
  void unite(int a, int b) {
    a = find(a), b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);  // the root is the smallest corner: deterministic
  }

 private:
  std::vector<int> parent_;
};

/// Corner index 3 f + c of vertex v in face f (the face must contain v).
int corner_of(const Triangles& F, int f, int v) {
  for (int c = 0; c < 3; ++c)
    if (F(f, c) == v) return 3 * f + c;
  return -1;
}

}  // namespace

CutMesh cut_mesh(const TriangleMesh& mesh, const MeshEdges& edges, const std::vector<std::array<int, 2>>& cuts) {
  const auto& F = mesh.faces();
  const int nf = mesh.num_faces(), nv = mesh.num_vertices();
  CutMesh out;
  std::vector<char> is_cut(edges.num_edges(), 0);
  std::vector<std::array<int, 2>> unknown;
  for (const auto& [a, b] : cuts) {
    const int e = edges.find(a, b);
    if (e < 0) {
      unknown.push_back({a, b});
    } else if (edges.num_faces(e) != 2) {
      out.already_cut.push_back(edges.vertices(e));
    } else {
      is_cut[e] = 1;
    }
  }
  refuse_unknown_edges(unknown, "cut");

  // Corners stay together across every edge that is not cut.
  Classes classes(3 * nf);
  std::vector<char> touches_cut(nv, 0);
  for (int e = 0; e < edges.num_edges(); ++e) {
    const auto& ends = edges.vertices(e);
    if (is_cut[e]) {
      touches_cut[ends[0]] = touches_cut[ends[1]] = 1;
      continue;
    }
    for (int k = 1; k < edges.num_faces(e); ++k)
      for (int v : ends) classes.unite(corner_of(F, edges.face(e, 0), v), corner_of(F, edges.face(e, k), v));
  }

  // New vertex of every corner: vertices away from the cuts keep their index (also non-manifold ones).
  Positions P = mesh.positions();
  std::vector<Eigen::Vector3d> extra;
  out.vertex_origin.resize(nv);
  std::iota(out.vertex_origin.begin(), out.vertex_origin.end(), 0);
  std::vector<int> corner_vertex(3 * static_cast<std::size_t>(nf), -1);
  std::map<int, int> root_vertex;  // class root -> new vertex (only for vertices on cuts)
  std::vector<char> vertex_taken(nv, 0);
  for (int f = 0; f < nf; ++f) {
    if (!mesh.face_active(f)) continue;
    for (int c = 0; c < 3; ++c) {
      const int v = F(f, c), corner = 3 * f + c;
      if (!touches_cut[v]) {
        corner_vertex[corner] = v;
        continue;
      }
      const int root = classes.find(corner);
      auto it = root_vertex.find(root);
      if (it == root_vertex.end()) {
        // Classes are met in order of their smallest corner (the root), so the first keeps the index.
        int id = v;
        if (vertex_taken[v]) {
          id = nv + static_cast<int>(extra.size());
          extra.push_back(P.row(v).transpose());
          out.vertex_origin.push_back(v);
        }
        vertex_taken[v] = 1;
        it = root_vertex.emplace(root, id).first;
      }
      corner_vertex[corner] = it->second;
    }
  }
  for (int e = 0; e < edges.num_edges(); ++e) {
    if (!is_cut[e]) continue;
    const int f = edges.face(e, 0), g = edges.face(e, 1);
    bool opened = false;
    for (int v : edges.vertices(e)) opened |= corner_vertex[corner_of(F, f, v)] != corner_vertex[corner_of(F, g, v)];
    if (opened)
      ++out.num_cut;
    else
      out.unopened.push_back(edges.vertices(e));
  }

  Positions positions(nv + static_cast<int>(extra.size()), 3);
  positions.topRows(nv) = P;
  for (std::size_t i = 0; i < extra.size(); ++i) positions.row(nv + static_cast<int>(i)) = extra[i].transpose();
  // Active faces get their corners' vertices. An excluded face keeps its vertices, except a duplicate of an
  // active face, which follows that face (otherwise it would stop being a duplicate and become active).
  std::map<std::array<int, 3>, int> active_by_vertices;
  for (int f = 0; f < nf; ++f)
    if (mesh.face_active(f)) {
      std::array<int, 3> key{F(f, 0), F(f, 1), F(f, 2)};
      std::sort(key.begin(), key.end());
      active_by_vertices.emplace(key, f);
    }
  Triangles faces = F;
  for (int f = 0; f < nf; ++f) {
    if (mesh.face_active(f)) {
      for (int c = 0; c < 3; ++c) faces(f, c) = corner_vertex[3 * f + c];
      continue;
    }
    std::array<int, 3> key{F(f, 0), F(f, 1), F(f, 2)};
    std::sort(key.begin(), key.end());
    const auto twin = active_by_vertices.find(key);
    if (twin == active_by_vertices.end()) continue;
    for (int c = 0; c < 3; ++c) faces(f, c) = corner_vertex[corner_of(F, twin->second, F(f, c))];
  }
  auto cut = std::make_shared<TriangleMesh>(positions, faces);
  for (int f = 0; f < nf; ++f)
    if (cut->face_active(f) != mesh.face_active(f))
      throw SolverError("cutting the mesh changed which faces are usable (face " + std::to_string(f) +
                        "): please report this mesh");
  out.mesh = std::move(cut);
  return out;
}

}  // namespace nfield
