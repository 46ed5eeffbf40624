// TriangleMesh: validation, cleaning, consistent orientation and dual-graph connectivity.
//
// Construction runs a fixed pipeline of small steps (each a free function below):
//   validate -> hash -> used vertices and bounding box -> classify faces (degenerate, duplicate, sliver)
//   -> undirected edge table of the active faces -> orientation (BFS per component, majority wins)
//   (which also yields the components) -> oriented faces and face geometry -> dual edges -> boundary and
//   non-manifold edges -> vertex stars (fans, rings, angle defects) -> Euler characteristic.
// Every step is deterministic: it depends only on the input arrays, never on hashing or addresses.
#include "nfield/mesh.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <utility>

#include "nfield/errors.hpp"

namespace nfield {
namespace {

using Eigen::Vector3d;

constexpr double kPi = 3.14159265358979323846;
/// A face is degenerate if area <= kDegenerateArea * bbox_diagonal^2 ...
constexpr double kDegenerateArea = 1e-14;
/// ... or if it is a needle: height over the longest edge 2A/L_max < kNeedleHeight * L_max.
constexpr double kNeedleHeight = 1e-7;
/// Sliver faces (kept, listed) have their smallest angle below one degree: tan(1 degree).
constexpr double kTanSliverAngle = 0.017455064928217585;
/// Supported extent of the used vertices. Downstream quantities are powers of it: areas L^2, energies of
/// order m up to L^(2-2m), spline solutions L^(2m) (order 4: L^8) and their squares in norms, L^16. At
/// 1e+-20 order-4 splines overflow (NaN fields, fuzz_mesh_ingestion found one) or underflow (lambda = 0);
/// 1e+-12 keeps all of them inside the double range with a margin of about 1e50.
constexpr double kMinExtent = 1e-12;
constexpr double kMaxExtent = 1e12;
/// At most this many indices are printed per summary line.
constexpr std::size_t kSummaryMaxIndices = 10;

// ------------------------------------------------------------------------------------------------ helpers

/// Disjoint-set forest with path halving; the root of a set is its smallest element (deterministic).
class UnionFind {
 public:
  explicit UnionFind(int n = 0) { reset(n); }
  /// n singletons {0}, ..., {n-1} (reuses the storage).
  void reset(int n) {
    parent_.resize(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) parent_[static_cast<std::size_t>(i)] = i;
  }
  int find(int x) {
    while (parent_[static_cast<std::size_t>(x)] != x) {
      int& p = parent_[static_cast<std::size_t>(x)];
      p = parent_[static_cast<std::size_t>(p)];
      x = p;
    }
    return x;
  }
  void unite(int a, int b) {
    a = find(a);
    b = find(b);
    if (a == b) return;
    if (a < b) std::swap(a, b);
    parent_[static_cast<std::size_t>(a)] = b;
  }

 private:
  std::vector<int> parent_;
};

/// FNV-1a-style 64-bit hash, continuing from state h: each 8-byte word w (host byte order) is folded in as
/// h = (h ^ w) * P, followed by h ^= h >> 32 so that high bits also reach the low ones; trailing bytes are
/// folded in one at a time. Word-wise for speed (a byte-wise FNV-1a costs milliseconds on large meshes).
std::uint64_t hash_bytes(std::uint64_t h, const void* data, std::size_t size) {
  constexpr std::uint64_t kPrime = 1099511628211ULL;
  const auto* bytes = static_cast<const unsigned char*>(data);
  std::size_t i = 0;
  for (; i + 8 <= size; i += 8) {
    std::uint64_t word;
    std::memcpy(&word, bytes + i, sizeof(word));
    h = (h ^ word) * kPrime;
    h ^= h >> 32;
  }
  for (; i < size; ++i) h = (h ^ bytes[i]) * kPrime;
  return h;
}

/// Content hash: hash_bytes over V and F (as int64), the positions (row-major doubles) and the input faces
/// (row-major int32), starting from the FNV offset basis.
std::uint64_t hash_mesh_content(const Positions& positions, const Triangles& faces) {
  std::uint64_t h = 14695981039346656037ULL;
  const std::int64_t counts[2] = {static_cast<std::int64_t>(positions.rows()),
                                  static_cast<std::int64_t>(faces.rows())};
  h = hash_bytes(h, counts, sizeof(counts));
  h = hash_bytes(h, positions.data(), static_cast<std::size_t>(positions.size()) * sizeof(double));
  h = hash_bytes(h, faces.data(), static_cast<std::size_t>(faces.size()) * sizeof(int));
  return h;
}

/// Key of the undirected edge {a, b} (a, b >= 0): (min << 32) | max. Sorting keys sorts edges
/// lexicographically by (smaller vertex, larger vertex).
inline std::uint64_t edge_key(int a, int b) {
  const auto lo = static_cast<std::uint64_t>(std::min(a, b));
  const auto hi = static_cast<std::uint64_t>(std::max(a, b));
  return (lo << 32) | hi;
}

/// Angle in [0, pi] between u and w, computed as atan2(|u x w|, u . w): accurate for tiny and
/// near-straight angles, and 0 (not NaN) if either vector vanishes.
inline double angle_between(const Vector3d& u, const Vector3d& w) {
  return std::atan2(u.cross(w).norm(), u.dot(w));
}

/// Interior angle of triangle (p0, p1, p2) at p0.
inline double triangle_angle(const Vector3d& p0, const Vector3d& p1, const Vector3d& p2) {
  return angle_between(p1 - p0, p2 - p0);
}

inline Vector3d vertex_position(const Positions& positions, int v) {
  return positions.row(v).transpose();
}

/// "face" / "faces" etc.
std::string plural(std::size_t count, const char* singular, const char* plural_form) {
  return std::to_string(count) + " " + (count == 1 ? singular : plural_form);
}

/// ": a, b, c, ... (N more)" with at most kSummaryMaxIndices items, each printed by `print`.
template <class T, class Print>
std::string index_list(const std::vector<T>& items, Print print) {
  std::ostringstream out;
  const std::size_t shown = std::min(items.size(), kSummaryMaxIndices);
  for (std::size_t i = 0; i < shown; ++i) {
    out << (i == 0 ? "" : ", ");
    print(out, items[i]);
  }
  if (items.size() > shown) out << ", ... (" << items.size() - shown << " more)";
  return out.str();
}

std::string int_list(const std::vector<int>& items) {
  return index_list(items, [](std::ostringstream& out, int i) { out << i; });
}

// ------------------------------------------------------------------------------------------------ validation

/// Rejects input that cannot be interpreted: empty arrays, sizes beyond int, non-finite coordinates,
/// indices outside [0, V).
void validate_input(const Positions& positions, const Triangles& faces) {
  constexpr auto kMaxInt = static_cast<Eigen::Index>(std::numeric_limits<int>::max());
  if (positions.rows() == 0) throw InputError("mesh has no vertices");
  if (faces.rows() == 0) throw InputError("mesh has no faces");
  if (positions.rows() > kMaxInt) throw InputError("mesh has too many vertices (more than 2^31 - 1)");
  // 3F half-edge ids must fit in int.
  if (faces.rows() > kMaxInt / 3) throw InputError("mesh has too many faces (more than (2^31 - 1) / 3)");
  for (Eigen::Index v = 0; v < positions.rows(); ++v) {
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite(positions(v, k))) {
        std::ostringstream msg;
        msg << "vertex " << v << " has a non-finite coordinate (" << positions(v, 0) << ", " << positions(v, 1)
            << ", " << positions(v, 2) << ")";
        throw InputError(msg.str());
      }
    }
  }
  const int num_vertices = static_cast<int>(positions.rows());
  for (Eigen::Index f = 0; f < faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = faces(f, k);
      if (v < 0 || v >= num_vertices) {
        std::ostringstream msg;
        msg << "face " << f << " references vertex " << v << ", outside the valid range 0.." << num_vertices - 1;
        throw InputError(msg.str());
      }
    }
  }
}

// ------------------------------------------------------------------------------------------------ vertices

/// Marks the vertices referenced by any input face and lists the others (ascending).
std::vector<char> used_vertices(int num_vertices, const Triangles& faces, std::vector<int>& unused) {
  std::vector<char> used(static_cast<std::size_t>(num_vertices), 0);
  for (Eigen::Index i = 0; i < faces.size(); ++i) used[static_cast<std::size_t>(faces.data()[i])] = 1;
  unused.clear();
  for (int v = 0; v < num_vertices; ++v)
    if (!used[static_cast<std::size_t>(v)]) unused.push_back(v);
  return used;
}

/// Diagonal length of the axis-aligned bounding box of the used vertices. Throws if it is outside
/// [kMinExtent, kMaxExtent] (but 0, all vertices at one point, is left for the "no usable face" check).
double used_bounding_box_diagonal(const Positions& positions, const std::vector<char>& used) {
  Vector3d lo = Vector3d::Constant(std::numeric_limits<double>::infinity());
  Vector3d hi = -lo;
  for (Eigen::Index v = 0; v < positions.rows(); ++v) {
    if (!used[static_cast<std::size_t>(v)]) continue;
    const Vector3d p = positions.row(v).transpose();
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  // Scale before taking the norm so that huge coordinates do not overflow.
  const Vector3d extent = hi - lo;
  const double scale = extent.cwiseAbs().maxCoeff();
  const double diagonal = (std::isfinite(scale) && scale > 0) ? scale * (extent / scale).norm() : scale;
  if (diagonal != 0 && !(diagonal >= kMinExtent && diagonal <= kMaxExtent)) {
    std::ostringstream msg;
    msg << "mesh extent (bounding box diagonal " << diagonal << ") is outside the supported range ["
        << kMinExtent << ", " << kMaxExtent << "]; rescale the coordinates";
    throw InputError(msg.str());
  }
  return diagonal;
}

// ------------------------------------------------------------------------------------------------ faces

/// True if the triangle is degenerate: area <= kDegenerateArea * diagonal^2, or a needle whose height
/// over its longest edge L is below kNeedleHeight * L (i.e. 2A < kNeedleHeight * L^2).
bool is_degenerate_triangle(const Vector3d& p0, const Vector3d& p1, const Vector3d& p2, double diagonal) {
  const Vector3d e0 = p1 - p0, e1 = p2 - p1, e2 = p0 - p2;
  const double longest_sq = std::max({e0.squaredNorm(), e1.squaredNorm(), e2.squaredNorm()});
  const double double_area = e0.cross(-e2).norm();
  if (0.5 * double_area <= kDegenerateArea * diagonal * diagonal) return true;
  return double_area < kNeedleHeight * longest_sq;
}

/// True if an interior angle of the triangle is below one degree. At a corner with edge vectors u, w the
/// angle is atan2(|u x w|, u.w), and |u x w| = 2A at every corner, so
/// angle < theta  <=>  u.w > 0 and 2A < tan(theta) u.w   (theta < pi/2); no trigonometry needed.
bool is_sliver_triangle(const Vector3d& p0, const Vector3d& p1, const Vector3d& p2) {
  const Vector3d e0 = p1 - p0, e1 = p2 - p1, e2 = p0 - p2;
  const double double_area = e0.cross(e1).norm();
  for (const double dot : {-e2.dot(e0), -e0.dot(e1), -e1.dot(e2)})
    if (dot > 0 && double_area < kTanSliverAngle * dot) return true;
  return false;
}

/// Classifies the input faces. A face is excluded (active = 0) if it is degenerate (repeated index or
/// geometrically degenerate) or has the same vertex set as an earlier non-degenerate face. Active faces with
/// a smallest angle below one degree are listed as slivers.
std::vector<char> classify_faces(const Positions& positions, const Triangles& faces, double diagonal,
                                 MeshReport& report) {
  const int num_faces = static_cast<int>(faces.rows());
  const int num_vertices = static_cast<int>(positions.rows());
  std::vector<char> active(static_cast<std::size_t>(num_faces), 1);
  for (int f = 0; f < num_faces; ++f) {
    const int a = faces(f, 0), b = faces(f, 1), c = faces(f, 2);
    const bool repeated = a == b || b == c || c == a;
    if (repeated || is_degenerate_triangle(vertex_position(positions, a), vertex_position(positions, b),
                                           vertex_position(positions, c), diagonal)) {
      active[static_cast<std::size_t>(f)] = 0;
      report.degenerate_faces.push_back(f);
    }
  }

  // Duplicates: group the remaining faces by smallest vertex (counting sort), order each group by
  // (middle vertex, largest vertex, face) and exclude all but the first face of each run of equal triples.
  std::vector<int> group(static_cast<std::size_t>(num_vertices) + 1, 0);
  std::vector<std::array<int, 3>> sorted(static_cast<std::size_t>(num_faces));
  for (int f = 0; f < num_faces; ++f) {
    if (!active[static_cast<std::size_t>(f)]) continue;
    std::array<int, 3>& v = sorted[static_cast<std::size_t>(f)];
    v = {faces(f, 0), faces(f, 1), faces(f, 2)};
    std::sort(v.begin(), v.end());
    ++group[static_cast<std::size_t>(v[0]) + 1];
  }
  for (std::size_t v = 0; v < static_cast<std::size_t>(num_vertices); ++v) group[v + 1] += group[v];
  std::vector<std::array<int, 3>> items(static_cast<std::size_t>(group.back()));  // (middle, largest, face)
  std::vector<int> fill(group.begin(), group.end() - 1);
  for (int f = 0; f < num_faces; ++f) {
    if (!active[static_cast<std::size_t>(f)]) continue;
    const std::array<int, 3>& v = sorted[static_cast<std::size_t>(f)];
    items[static_cast<std::size_t>(fill[static_cast<std::size_t>(v[0])]++)] = {v[1], v[2], f};
  }
  for (std::size_t v = 0; v < static_cast<std::size_t>(num_vertices); ++v) {
    const auto begin = items.begin() + group[v], end = items.begin() + group[v + 1];
    std::sort(begin, end);
    for (auto it = begin; it != end && it + 1 != end; ++it) {
      if ((*it)[0] == (*(it + 1))[0] && (*it)[1] == (*(it + 1))[1]) {
        active[static_cast<std::size_t>((*(it + 1))[2])] = 0;
        report.duplicate_faces.push_back((*(it + 1))[2]);
      }
    }
  }
  std::sort(report.duplicate_faces.begin(), report.duplicate_faces.end());

  for (int f = 0; f < num_faces; ++f) {
    if (!active[static_cast<std::size_t>(f)]) continue;
    if (is_sliver_triangle(vertex_position(positions, faces(f, 0)), vertex_position(positions, faces(f, 1)),
                           vertex_position(positions, faces(f, 2))))
      report.sliver_faces.push_back(f);
  }
  return active;
}

// ------------------------------------------------------------------------------------------------ edges

/// Undirected edges of the active faces. Half-edge h = 3f + c runs from corner c to corner (c+1)%3 of
/// face f in the *input* winding. Edges are numbered in increasing key order (smaller vertex, then larger);
/// the half-edges of edge e are halfedges[first[e] .. first[e+1]), ascending.
struct EdgeTable {
  std::vector<std::uint64_t> key;
  std::vector<int> first;
  std::vector<int> halfedges;
  std::vector<int> edge_of;  ///< per half-edge (3F); -1 on inactive faces

  int num_edges() const { return static_cast<int>(key.size()); }
  int face_count(int e) const { return first[static_cast<std::size_t>(e) + 1] - first[static_cast<std::size_t>(e)]; }
  /// For an edge with exactly two half-edges, the one that is not h.
  int other_halfedge(int e, int h) const {
    const int h0 = halfedges[static_cast<std::size_t>(first[static_cast<std::size_t>(e)])];
    return h0 == h ? halfedges[static_cast<std::size_t>(first[static_cast<std::size_t>(e)]) + 1] : h0;
  }
};

/// Builds the edge table. Sorting (edge key, half-edge) pairs is done as a counting sort on the smaller
/// vertex followed by a sort of each (small) bucket on (larger vertex, half-edge): linear time in practice.
EdgeTable build_edge_table(const Triangles& faces, const std::vector<char>& active, int num_vertices) {
  const int num_faces = static_cast<int>(faces.rows());
  std::vector<int> bucket(static_cast<std::size_t>(num_vertices) + 1, 0);
  for (int f = 0; f < num_faces; ++f) {
    if (!active[static_cast<std::size_t>(f)]) continue;
    for (int c = 0; c < 3; ++c) ++bucket[static_cast<std::size_t>(std::min(faces(f, c), faces(f, (c + 1) % 3))) + 1];
  }
  for (std::size_t v = 0; v < static_cast<std::size_t>(num_vertices); ++v) bucket[v + 1] += bucket[v];

  // (larger vertex, half-edge), grouped by smaller vertex; half-edges ascending within each group.
  std::vector<std::pair<int, int>> items(static_cast<std::size_t>(bucket.back()));
  std::vector<int> fill(bucket.begin(), bucket.end() - 1);
  for (int f = 0; f < num_faces; ++f) {
    if (!active[static_cast<std::size_t>(f)]) continue;
    for (int c = 0; c < 3; ++c) {
      const int a = faces(f, c), b = faces(f, (c + 1) % 3);
      items[static_cast<std::size_t>(fill[static_cast<std::size_t>(std::min(a, b))]++)] = {std::max(a, b), 3 * f + c};
    }
  }
  for (std::size_t v = 0; v < static_cast<std::size_t>(num_vertices); ++v)
    std::sort(items.begin() + bucket[v], items.begin() + bucket[v + 1]);

  EdgeTable table;
  table.edge_of.assign(static_cast<std::size_t>(num_faces) * 3, -1);
  table.halfedges.reserve(items.size());
  table.first.reserve(items.size() / 2 + 2);
  table.key.reserve(items.size() / 2 + 1);
  for (int v = 0; v < num_vertices; ++v) {
    for (int i = bucket[static_cast<std::size_t>(v)]; i < bucket[static_cast<std::size_t>(v) + 1]; ++i) {
      const auto [larger, h] = items[static_cast<std::size_t>(i)];
      const std::uint64_t key = edge_key(v, larger);
      if (table.key.empty() || table.key.back() != key) {
        table.key.push_back(key);
        table.first.push_back(i);
      }
      table.halfedges.push_back(h);
      table.edge_of[static_cast<std::size_t>(h)] = table.num_edges() - 1;
    }
  }
  table.first.push_back(static_cast<int>(items.size()));
  return table;
}

/// Start vertex of input half-edge h.
inline int halfedge_tail(const Triangles& faces, int h) { return faces(h / 3, h % 3); }

// ------------------------------------------------------------------------------------------------ orientation

/// Orientation of the active faces: which faces to flip, and which manifold edges remain inconsistent.
struct Orientation {
  std::vector<char> flipped;   ///< per face
  std::vector<int> component;  ///< per face: component through manifold edges (-1 inactive), by smallest face
  int num_components = 0;
  std::vector<char> edge_cut;  ///< per edge: manifold edge whose two faces still disagree
  int num_cuts = 0;
};

/// Orients every connected component (through edges with exactly two active faces) by a breadth-first
/// walk from its smallest face: a neighbour across edge {a, b} must traverse it in the opposite direction,
/// so it is flipped iff (it traverses the edge like its parent) XOR (the parent is flipped). Afterwards the
/// majority wins: if more than half of the component's faces are flipped, the whole choice is inverted.
/// Manifold edges whose faces still disagree (non-orientable components) become cuts.
///
/// The components are also those of the dual graph: every BFS tree edge is consistent by construction (and
/// stays so when a component is inverted), so it is a dual edge; conversely every dual edge is manifold.
Orientation orient_faces(const Triangles& faces, const std::vector<char>& active, const EdgeTable& edges) {
  const int num_faces = static_cast<int>(faces.rows());
  Orientation result;
  result.flipped.assign(static_cast<std::size_t>(num_faces), 0);
  result.component.assign(static_cast<std::size_t>(num_faces), -1);
  std::vector<int> queue;
  queue.reserve(static_cast<std::size_t>(num_faces));

  for (int seed = 0; seed < num_faces; ++seed) {
    if (!active[static_cast<std::size_t>(seed)] || result.component[static_cast<std::size_t>(seed)] >= 0) continue;
    const int label = result.num_components++;
    queue.clear();
    queue.push_back(seed);
    result.component[static_cast<std::size_t>(seed)] = label;
    std::size_t num_flipped = 0;
    for (std::size_t head = 0; head < queue.size(); ++head) {
      const int f = queue[head];
      for (int c = 0; c < 3; ++c) {
        const int h = 3 * f + c;
        const int e = edges.edge_of[static_cast<std::size_t>(h)];
        if (edges.face_count(e) != 2) continue;
        const int g_h = edges.other_halfedge(e, h);
        const int g = g_h / 3;
        if (result.component[static_cast<std::size_t>(g)] >= 0) continue;
        const bool same_direction = halfedge_tail(faces, h) == halfedge_tail(faces, g_h);
        const bool flip = same_direction != static_cast<bool>(result.flipped[static_cast<std::size_t>(f)]);
        result.flipped[static_cast<std::size_t>(g)] = flip;
        num_flipped += flip;
        result.component[static_cast<std::size_t>(g)] = label;
        queue.push_back(g);
      }
    }
    if (2 * num_flipped > queue.size())
      for (int f : queue) result.flipped[static_cast<std::size_t>(f)] ^= 1;
  }

  result.edge_cut.assign(static_cast<std::size_t>(edges.num_edges()), 0);
  for (int e = 0; e < edges.num_edges(); ++e) {
    if (edges.face_count(e) != 2) continue;
    const int h0 = edges.halfedges[static_cast<std::size_t>(edges.first[static_cast<std::size_t>(e)])];
    const int h1 = edges.other_halfedge(e, h0);
    const bool same_direction = halfedge_tail(faces, h0) == halfedge_tail(faces, h1);
    const bool one_flipped = result.flipped[static_cast<std::size_t>(h0 / 3)] !=
                             result.flipped[static_cast<std::size_t>(h1 / 3)];
    if (same_direction != one_flipped) {
      result.edge_cut[static_cast<std::size_t>(e)] = 1;
      ++result.num_cuts;
    }
  }
  return result;
}

/// A flipped face (a, b, c) is stored as (a, c, b). Its edge c' (from corner c' to c'+1) is the input
/// edge kFlippedEdge[c'] traversed backwards; the map is an involution.
constexpr int kFlippedEdge[3] = {2, 1, 0};

/// Local edge index in the oriented face of the input half-edge h.
inline int oriented_local_edge(int h, const std::vector<char>& flipped) {
  const int c = h % 3;
  return flipped[static_cast<std::size_t>(h / 3)] ? kFlippedEdge[c] : c;
}

/// Faces with two indices swapped where flipped.
Triangles oriented_faces(const Triangles& faces, const std::vector<char>& flipped) {
  Triangles result = faces;
  for (Eigen::Index f = 0; f < faces.rows(); ++f)
    if (flipped[static_cast<std::size_t>(f)]) std::swap(result(f, 1), result(f, 2));
  return result;
}

// ------------------------------------------------------------------------------------------------ dual graph

/// Dual edges and, per oriented face-edge slot 3f + c (edge from corner c to c+1 of faces()), the dual edge
/// across it (-1 if none).
struct DualGraph {
  std::vector<DualEdge> edges;
  std::vector<int> slot_dual;
};

/// One dual edge per manifold, non-cut edge, sorted by (face0, face1) with face0 < face1; vertex0 -> vertex1
/// is the shared edge as directed in face0's oriented winding.
DualGraph build_dual_graph(const Triangles& oriented, const EdgeTable& edges, const Orientation& orientation) {
  const int num_faces = static_cast<int>(oriented.rows());
  DualGraph dual;
  dual.slot_dual.assign(static_cast<std::size_t>(num_faces) * 3, -1);
  struct Link {
    int neighbour, local_edge, neighbour_halfedge;
  };
  for (int f = 0; f < num_faces; ++f) {
    Link links[3];
    int count = 0;
    for (int c = 0; c < 3; ++c) {
      const int h = 3 * f + (orientation.flipped[static_cast<std::size_t>(f)] ? kFlippedEdge[c] : c);
      const int e = edges.edge_of[static_cast<std::size_t>(h)];
      if (e < 0 || edges.face_count(e) != 2 || orientation.edge_cut[static_cast<std::size_t>(e)]) continue;
      const int g_h = edges.other_halfedge(e, h);
      if (g_h / 3 > f) links[count++] = {g_h / 3, c, g_h};  // smaller neighbours created it already
    }
    for (int i = 1; i < count; ++i)  // insertion sort of at most three links by neighbour
      for (int j = i; j > 0 && links[j].neighbour < links[j - 1].neighbour; --j) std::swap(links[j], links[j - 1]);
    for (int i = 0; i < count; ++i) {
      const Link& link = links[i];
      const int id = static_cast<int>(dual.edges.size());
      dual.edges.push_back({f, link.neighbour, oriented(f, link.local_edge), oriented(f, (link.local_edge + 1) % 3)});
      dual.slot_dual[static_cast<std::size_t>(3 * f + link.local_edge)] = id;
      dual.slot_dual[static_cast<std::size_t>(3 * link.neighbour +
                                              oriented_local_edge(link.neighbour_halfedge, orientation.flipped))] = id;
    }
  }
  return dual;
}

// ------------------------------------------------------------------------------------------------ boundary

/// Boundary edges are edges with exactly one active face, plus orientation cuts. Counts them and the
/// connected components of the graph they form (boundary loops).
void count_boundary(const EdgeTable& edges, const Orientation& orientation, int num_vertices, MeshReport& report) {
  UnionFind loops(num_vertices);
  std::vector<char> on_boundary(static_cast<std::size_t>(num_vertices), 0);
  int num_boundary = 0;
  for (int e = 0; e < edges.num_edges(); ++e) {
    if (edges.face_count(e) != 1 && !orientation.edge_cut[static_cast<std::size_t>(e)]) continue;
    const std::uint64_t key = edges.key[static_cast<std::size_t>(e)];
    const int a = static_cast<int>(key >> 32), b = static_cast<int>(key & 0xffffffffULL);
    loops.unite(a, b);
    on_boundary[static_cast<std::size_t>(a)] = on_boundary[static_cast<std::size_t>(b)] = 1;
    ++num_boundary;
  }
  int num_loops = 0;
  for (int v = 0; v < num_vertices; ++v)
    if (on_boundary[static_cast<std::size_t>(v)] && loops.find(v) == v) ++num_loops;
  report.num_boundary_edges = num_boundary;
  report.num_boundary_loops = num_loops;
}

/// Edges with more than two active faces, as sorted vertex pairs (in key order, hence sorted).
void list_nonmanifold_edges(const EdgeTable& edges, MeshReport& report) {
  for (int e = 0; e < edges.num_edges(); ++e) {
    if (edges.face_count(e) <= 2) continue;
    const std::uint64_t key = edges.key[static_cast<std::size_t>(e)];
    report.nonmanifold_edges.push_back({static_cast<int>(key >> 32), static_cast<int>(key & 0xffffffffULL)});
  }
}

// ------------------------------------------------------------------------------------------------ vertex stars

/// An active corner seen from its vertex v: face with oriented winding (v, next, prev), the dual edge across
/// its edge {prev, v} (-1 if none) and its interior angle at v.
struct Corner {
  int face, next, prev, dual_prev;
  double angle;
};

/// The active corners of every vertex (CSR, ascending face index): corners[first[v] .. first[v+1]).
struct VertexCorners {
  std::vector<int> first;
  std::vector<Corner> corners;
};

/// Gathers the active corners by vertex, with their angles atan2(|u x w|, u . w).
VertexCorners gather_corners(const Positions& positions, const Triangles& oriented, const std::vector<char>& active,
                             const DualGraph& dual, int num_vertices) {
  const int num_faces = static_cast<int>(oriented.rows());
  VertexCorners star;
  star.first.assign(static_cast<std::size_t>(num_vertices) + 1, 0);
  for (int f = 0; f < num_faces; ++f)
    if (active[static_cast<std::size_t>(f)])
      for (int c = 0; c < 3; ++c) ++star.first[static_cast<std::size_t>(oriented(f, c)) + 1];
  for (std::size_t v = 0; v < static_cast<std::size_t>(num_vertices); ++v) star.first[v + 1] += star.first[v];

  star.corners.resize(static_cast<std::size_t>(star.first.back()));
  std::vector<int> fill(star.first.begin(), star.first.end() - 1);
  for (int f = 0; f < num_faces; ++f) {
    if (!active[static_cast<std::size_t>(f)]) continue;
    const int v[3] = {oriented(f, 0), oriented(f, 1), oriented(f, 2)};
    const Vector3d p[3] = {vertex_position(positions, v[0]), vertex_position(positions, v[1]),
                           vertex_position(positions, v[2])};
    for (int c = 0; c < 3; ++c) {
      const int n = (c + 1) % 3, q = (c + 2) % 3;
      star.corners[static_cast<std::size_t>(fill[static_cast<std::size_t>(v[c])]++)] = {
          f, v[n], v[q], dual.slot_dual[static_cast<std::size_t>(3 * f + q)], triangle_angle(p[c], p[n], p[q])};
    }
  }
  return star;
}

/// Local analysis of the k active corners around one vertex v. Every active face containing an edge {v, x}
/// has a corner at v, so the faces of that edge are exactly the local corners listing x as next or prev; the
/// edge is manifold iff there are two. Scratch storage is reused from vertex to vertex.
class StarAnalysis {
 public:
  void reset(const Corner* corners, int k) {
    corners_ = corners;
    k_ = k;
    links_.clear();
  }

  /// Number of fans: components of the corners linked across manifold edges.
  int count_fans() {
    build_links();
    fans_.reset(k_);
    for (std::size_t i = 0; i < links_.size();) {
      std::size_t j = i;
      while (j < links_.size() && links_[j].first == links_[i].first) ++j;
      if (j - i == 2) fans_.unite(links_[i].second, links_[i + 1].second);
      i = j;
    }
    int count = 0;
    for (int i = 0; i < k_; ++i) count += fans_.find(i) == i;
    return count;
  }

  /// Walks counter-clockwise from corner 0: in face (v, a, b) the next face is the one across the dual edge at
  /// {b, v}; it contains v -> b, i.e. it is the corner whose `next` is b. Fills the ring and returns true iff
  /// every step crosses a dual edge and the walk closes after visiting all k corners (then v has one fan).
  bool walk_closed_ring(std::vector<int>& ring_faces, std::vector<int>& ring_dual) {
    ring_faces.clear();
    ring_dual.clear();
    int current = 0;
    for (int step = 0; step < k_; ++step) {
      const Corner& corner = corners_[current];
      if (corner.dual_prev < 0) break;
      ring_faces.push_back(corner.face);
      ring_dual.push_back(corner.dual_prev);
      current = corner_with_next(corner.prev);  // unique: the dual edge makes {v, prev} manifold and consistent
      if (current <= 0) break;
    }
    if (current == 0 && static_cast<int>(ring_faces.size()) == k_) return true;
    ring_faces.clear();
    ring_dual.clear();
    return false;
  }

 private:
  /// (neighbour vertex, local corner) for both neighbours of every corner, sorted; built on demand.
  void build_links() {
    if (!links_.empty()) return;
    for (int i = 0; i < k_; ++i) {
      links_.push_back({corners_[i].next, i});
      links_.push_back({corners_[i].prev, i});
    }
    std::sort(links_.begin(), links_.end());
  }

  /// Local index of a corner whose next vertex is x (-1 if none): a scan for small stars, else a search
  /// through the sorted links.
  int corner_with_next(int x) {
    constexpr int kScanLimit = 32;
    if (k_ <= kScanLimit) {
      for (int i = 0; i < k_; ++i)
        if (corners_[i].next == x) return i;
      return -1;
    }
    build_links();
    for (auto it = std::lower_bound(links_.begin(), links_.end(), std::make_pair(x, -1));
         it != links_.end() && it->first == x; ++it)
      if (corners_[it->second].next == x) return it->second;
    return -1;
  }

  const Corner* corners_ = nullptr;
  int k_ = 0;
  std::vector<std::pair<int, int>> links_;
  UnionFind fans_;
};

/// Vertices that belong to an excluded (degenerate or duplicate) face: they get no ring.
std::vector<char> vertices_touching_excluded(const Triangles& faces, const std::vector<char>& active, int num_vertices) {
  std::vector<char> touches(static_cast<std::size_t>(num_vertices), 0);
  for (Eigen::Index f = 0; f < faces.rows(); ++f)
    if (!active[static_cast<std::size_t>(f)])
      for (int c = 0; c < 3; ++c) touches[static_cast<std::size_t>(faces(f, c))] = 1;
  return touches;
}

/// Everything TriangleMesh stores per vertex.
struct VertexStructure {
  std::vector<std::vector<int>> faces, ring_faces, ring_dual_edges;
  std::vector<double> angle_defect;
  std::vector<int> nonmanifold;  ///< ascending
  int num_active = 0;            ///< vertices with at least one active face
};

/// Per vertex: the incident active faces; the closed counter-clockwise ring where the vertex is interior
/// (no excluded face touches it and the walk closes), with angle defect K_v = 2 pi - sum of corner angles;
/// otherwise the number of fans, more than one making the vertex non-manifold.
VertexStructure analyse_vertices(const VertexCorners& star, const std::vector<char>& touches_excluded) {
  const std::size_t num_vertices = touches_excluded.size();
  VertexStructure result;
  result.faces.resize(num_vertices);
  result.ring_faces.resize(num_vertices);
  result.ring_dual_edges.resize(num_vertices);
  result.angle_defect.assign(num_vertices, 0.0);
  StarAnalysis analysis;
  std::vector<int> ring_faces, ring_dual;
  for (std::size_t v = 0; v < num_vertices; ++v) {
    const Corner* corners = star.corners.data() + star.first[v];
    const int k = star.first[v + 1] - star.first[v];
    if (k == 0) continue;
    ++result.num_active;
    std::vector<int>& incident = result.faces[v];
    incident.resize(static_cast<std::size_t>(k));
    for (int i = 0; i < k; ++i) incident[static_cast<std::size_t>(i)] = corners[i].face;

    analysis.reset(corners, k);
    if (touches_excluded[v] || !analysis.walk_closed_ring(ring_faces, ring_dual)) {
      if (analysis.count_fans() > 1) result.nonmanifold.push_back(static_cast<int>(v));
      continue;
    }
    result.ring_faces[v].assign(ring_faces.begin(), ring_faces.end());
    result.ring_dual_edges[v].assign(ring_dual.begin(), ring_dual.end());
    double angle_sum = 0;
    for (int i = 0; i < k; ++i) angle_sum += corners[i].angle;
    result.angle_defect[v] = 2 * kPi - angle_sum;
  }
  return result;
}

// ------------------------------------------------------------------------------------------------ per-face output

/// Unit normals N = (p1 - p0) x (p2 - p0) / |...| and areas A = |...| / 2 of the active oriented faces
/// (zero for excluded faces; an active face has A > 0 by construction).
void face_geometry(const Positions& positions, const Triangles& oriented, const std::vector<char>& active,
                   std::vector<Vector3d>& normals, std::vector<double>& areas, double& total_area) {
  const auto num_faces = static_cast<std::size_t>(oriented.rows());
  normals.assign(num_faces, Vector3d::Zero());
  areas.assign(num_faces, 0.0);
  total_area = 0;
  for (int f = 0; f < oriented.rows(); ++f) {
    if (!active[static_cast<std::size_t>(f)]) continue;
    const Vector3d p0 = vertex_position(positions, oriented(f, 0));
    const Vector3d cross =
        (vertex_position(positions, oriented(f, 1)) - p0).cross(vertex_position(positions, oriented(f, 2)) - p0);
    const double norm = cross.norm();
    normals[static_cast<std::size_t>(f)] = cross / norm;
    areas[static_cast<std::size_t>(f)] = 0.5 * norm;
    total_area += 0.5 * norm;
  }
}

/// Per face, the dual edges across its edges 0, 1, 2 (in that order, skipping edges without one).
std::vector<std::vector<int>> face_dual_lists(const DualGraph& dual, int num_faces) {
  std::vector<std::vector<int>> lists(static_cast<std::size_t>(num_faces));
  for (int f = 0; f < num_faces; ++f) {
    int slots[3], count = 0;
    for (int c = 0; c < 3; ++c) {
      const int d = dual.slot_dual[static_cast<std::size_t>(3 * f + c)];
      if (d >= 0) slots[count++] = d;
    }
    lists[static_cast<std::size_t>(f)].assign(slots, slots + count);
  }
  return lists;
}

}  // namespace

// ------------------------------------------------------------------------------------------------ MeshReport

std::vector<std::string> MeshReport::summary() const {
  std::vector<std::string> lines;
  const auto n = [](const auto& items) { return items.size(); };
  if (!unused_vertices.empty())
    lines.push_back(plural(n(unused_vertices), "unused vertex", "unused vertices") + " (ignored)");
  if (!degenerate_faces.empty())
    lines.push_back(plural(n(degenerate_faces), "degenerate face", "degenerate faces") +
                    " (zero area, needle or repeated vertex), excluded: " + int_list(degenerate_faces));
  if (!duplicate_faces.empty())
    lines.push_back(plural(n(duplicate_faces), "duplicate face", "duplicate faces") +
                    " (same vertices as an earlier face), excluded: " + int_list(duplicate_faces));
  if (!sliver_faces.empty())
    lines.push_back(plural(n(sliver_faces), "sliver face", "sliver faces") +
                    " (smallest angle < 1\xC2\xB0), kept: " + int_list(sliver_faces));
  if (!nonmanifold_edges.empty())
    lines.push_back(plural(n(nonmanifold_edges), "non-manifold edge", "non-manifold edges") +
                    " (more than two faces), cut: " +
                    index_list(nonmanifold_edges, [](std::ostringstream& out, const std::array<int, 2>& e) {
                      out << "(" << e[0] << ", " << e[1] << ")";
                    }));
  if (!nonmanifold_vertices.empty())
    lines.push_back(plural(n(nonmanifold_vertices), "non-manifold vertex", "non-manifold vertices") +
                    " (faces do not form one fan), no singularity index: " + int_list(nonmanifold_vertices));
  if (!flipped_faces.empty())
    lines.push_back(plural(n(flipped_faces), "face", "faces") +
                    " re-oriented to agree with their neighbours: " + int_list(flipped_faces));
  if (num_orientation_cuts > 0)
    lines.push_back(plural(static_cast<std::size_t>(num_orientation_cuts), "edge", "edges") +
                    " cut because the surface is not orientable (treated as boundary)");
  if (num_boundary_loops > 0)
    lines.push_back(plural(static_cast<std::size_t>(num_boundary_loops), "boundary loop", "boundary loops") + " (" +
                    plural(static_cast<std::size_t>(num_boundary_edges), "edge", "edges") + ")");
  if (num_components > 1)
    lines.push_back(std::to_string(num_components) + " connected components (no coupling between them)");
  return lines;
}

// ------------------------------------------------------------------------------------------------ TriangleMesh

TriangleMesh::TriangleMesh(const Positions& positions, const Triangles& faces) {
  validate_input(positions, faces);
  const int num_vertices = static_cast<int>(positions.rows());
  const int num_faces = static_cast<int>(faces.rows());
  positions_ = positions;
  hash_ = hash_mesh_content(positions, faces);
  report_.num_input_vertices = num_vertices;
  report_.num_input_faces = num_faces;

  // Vertices, scale, face classification.
  const std::vector<char> used = used_vertices(num_vertices, faces, report_.unused_vertices);
  bbox_diagonal_ = used_bounding_box_diagonal(positions, used);
  const std::vector<char> active = classify_faces(positions, faces, bbox_diagonal_, report_);
  face_active_.assign(active.begin(), active.end());
  num_active_faces_ = static_cast<int>(std::count(active.begin(), active.end(), 1));
  if (num_active_faces_ == 0) {
    std::ostringstream msg;
    msg << "mesh has no usable face: all " << num_faces
        << " faces are degenerate (zero area, needle or repeated vertex) or duplicates";
    throw InputError(msg.str());
  }

  // Connectivity and orientation.
  const EdgeTable edges = build_edge_table(faces, active, num_vertices);
  Orientation orientation = orient_faces(faces, active, edges);
  faces_ = oriented_faces(faces, orientation.flipped);
  for (int f = 0; f < num_faces; ++f)
    if (orientation.flipped[static_cast<std::size_t>(f)]) report_.flipped_faces.push_back(f);
  report_.num_orientation_cuts = orientation.num_cuts;

  face_geometry(positions_, faces_, active, normals_, areas_, total_area_);

  // Dual graph; its components are those found while orienting.
  DualGraph dual = build_dual_graph(faces_, edges, orientation);
  face_dual_edges_ = face_dual_lists(dual, num_faces);
  dual_edges_ = std::move(dual.edges);
  face_neighbors_.assign(static_cast<std::size_t>(num_faces), {-1, -1, -1});
  for (int f = 0; f < num_faces; ++f)
    for (std::size_t k = 0; k < face_dual_edges_[static_cast<std::size_t>(f)].size(); ++k) {
      const DualEdge& d = dual_edges_[static_cast<std::size_t>(face_dual_edges_[static_cast<std::size_t>(f)][k])];
      face_neighbors_[static_cast<std::size_t>(f)][k] = d.face0 == f ? d.face1 : d.face0;
    }
  face_component_ = std::move(orientation.component);
  report_.num_components = orientation.num_components;

  // Boundary and non-manifold edges.
  count_boundary(edges, orientation, num_vertices, report_);
  list_nonmanifold_edges(edges, report_);

  // Vertex stars: incident faces, rings, angle defects, non-manifold vertices.
  VertexStructure vertices = analyse_vertices(gather_corners(positions_, faces_, active, dual, num_vertices),
                                              vertices_touching_excluded(faces_, active, num_vertices));
  vertex_faces_ = std::move(vertices.faces);
  vertex_ring_faces_ = std::move(vertices.ring_faces);
  vertex_ring_dual_edges_ = std::move(vertices.ring_dual_edges);
  angle_defect_ = std::move(vertices.angle_defect);
  report_.nonmanifold_vertices = std::move(vertices.nonmanifold);

  // Euler characteristic of the active part: V (vertices of active faces) - E + F.
  report_.euler_characteristic = vertices.num_active - edges.num_edges() + num_active_faces_;
}

double TriangleMesh::corner_angle(int f, int c) const {
  if (f < 0 || f >= num_faces() || c < 0 || c > 2) {
    std::ostringstream msg;
    msg << "corner_angle: face " << f << " / corner " << c << " out of range (" << num_faces() << " faces)";
    throw ParameterError(msg.str());
  }
  return triangle_angle(vertex_position(positions_, faces_(f, c)), vertex_position(positions_, faces_(f, (c + 1) % 3)),
                        vertex_position(positions_, faces_(f, (c + 2) % 3)));
}

}  // namespace nfield
