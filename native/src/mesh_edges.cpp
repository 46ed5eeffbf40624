#include "nfield/mesh_edges.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "nfield/errors.hpp"

namespace nfield {
namespace {

inline std::uint64_t edge_key(int a, int b) {
  const auto lo = static_cast<std::uint64_t>(std::min(a, b));
  const auto hi = static_cast<std::uint64_t>(std::max(a, b));
  return (lo << 32) | hi;
}

}  // namespace

MeshEdges::MeshEdges(const TriangleMesh& mesh) {
  const auto& F = mesh.faces();
  const int nf = mesh.num_faces();
  // (key, face, corner) for every corner edge of an active face, sorted by key then face.
  struct Corner {
    std::uint64_t key;
    int face, corner;
  };
  std::vector<Corner> corners;
  corners.reserve(3 * static_cast<std::size_t>(mesh.num_active_faces()));
  for (int f = 0; f < nf; ++f) {
    if (!mesh.face_active(f)) continue;
    for (int c = 0; c < 3; ++c) corners.push_back({edge_key(F(f, c), F(f, (c + 1) % 3)), f, c});
  }
  std::sort(corners.begin(), corners.end(), [](const Corner& a, const Corner& b) {
    return a.key != b.key ? a.key < b.key : (a.face != b.face ? a.face < b.face : a.corner < b.corner);
  });
  face_edges_.assign(3 * static_cast<std::size_t>(nf), -1);
  offsets_.push_back(0);
  for (std::size_t i = 0; i < corners.size();) {
    const std::uint64_t key = corners[i].key;
    const int e = static_cast<int>(keys_.size());
    keys_.push_back(key);
    vertices_.push_back({static_cast<int>(key >> 32), static_cast<int>(key & 0xffffffffULL)});
    int last_face = -1;
    for (; i < corners.size() && corners[i].key == key; ++i) {
      face_edges_[3 * static_cast<std::size_t>(corners[i].face) + corners[i].corner] = e;
      // A face with a repeated vertex pair is degenerate, hence inactive: each face appears once per edge.
      if (corners[i].face != last_face) faces_.push_back(corners[i].face);
      last_face = corners[i].face;
    }
    offsets_.push_back(static_cast<int>(faces_.size()));
  }
}

int MeshEdges::find(int a, int b) const {
  if (a < 0 || b < 0 || a == b) return -1;
  const std::uint64_t key = edge_key(a, b);
  const auto it = std::lower_bound(keys_.begin(), keys_.end(), key);
  return it != keys_.end() && *it == key ? static_cast<int>(it - keys_.begin()) : -1;
}

double MeshEdges::dihedral_angle(const TriangleMesh& mesh, int e) const {
  if (num_faces(e) != 2) return -1.0;
  const Eigen::Vector3d& n0 = mesh.face_normal(face(e, 0));
  const Eigen::Vector3d& n1 = mesh.face_normal(face(e, 1));
  return std::atan2(n0.cross(n1).norm(), n0.dot(n1));
}

void refuse_unknown_edges(const std::vector<std::array<int, 2>>& unknown, const std::string& what) {
  if (unknown.empty()) return;
  std::ostringstream msg;
  msg << unknown.size() << " " << what << " edge(s) are not edges of the mesh's usable faces, e.g.";
  for (std::size_t i = 0; i < std::min<std::size_t>(unknown.size(), 5); ++i)
    msg << " (" << unknown[i][0] << ", " << unknown[i][1] << ")";
  throw InputError(msg.str());
}

}  // namespace nfield
