#include "nfield/features.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "nfield/errors.hpp"
#include "nfield/face_regions.hpp"

namespace nfield {
namespace {

constexpr double kDegree = M_PI / 180.0;

/// The feature edges with the vertex they are walked from: edge e of chain goes vertices[i] -> vertices[i+1].
Eigen::Vector3d chain_edge_vector(const TriangleMesh& mesh, const FeatureChain& chain, std::size_t i) {
  const auto& P = mesh.positions();
  return (P.row(chain.vertices[i + 1]) - P.row(chain.vertices[i])).transpose();
}

}  // namespace

FeatureSet detect_features(const TriangleMesh& mesh, const MeshEdges& edges, const FeatureOptions& options) {
  if (!(options.sharp_angle < 180.0))
    throw ParameterError("sharp angle must be below 180 degrees (negative: no sharp edges)");
  if (!(options.corner_angle >= 0.0 && options.corner_angle <= 180.0))
    throw ParameterError("corner angle must lie in [0, 180] degrees");
  FeatureSet out;
  std::vector<char> is_feature(edges.num_edges(), 0);
  for (int e = 0; e < edges.num_edges(); ++e) {
    if (options.boundary && edges.is_boundary(e)) {
      is_feature[e] = 1;
      ++out.num_boundary;
    } else if (options.sharp_angle >= 0 && edges.dihedral_angle(mesh, e) > options.sharp_angle * kDegree) {
      is_feature[e] = 1;
      ++out.num_sharp;
    }
  }
  std::vector<std::array<int, 2>> unknown;
  for (const auto& [a, b] : options.edges) {
    const int e = edges.find(a, b);
    if (e < 0) {
      unknown.push_back({a, b});
      continue;
    }
    if (!is_feature[e]) is_feature[e] = 1, ++out.num_marked;
  }
  refuse_unknown_edges(unknown, "marked feature");
  for (int e = 0; e < edges.num_edges(); ++e)
    if (is_feature[e]) out.edges.push_back(e);

  // Feature edges around each vertex.
  const int nv = mesh.num_vertices();
  std::vector<std::vector<int>> at(nv);
  for (int e : out.edges) {
    at[edges.vertices(e)[0]].push_back(e);
    at[edges.vertices(e)[1]].push_back(e);
  }
  const auto& P = mesh.positions();
  auto other = [&](int e, int v) { return edges.vertices(e)[0] == v ? edges.vertices(e)[1] : edges.vertices(e)[0]; };
  // A vertex passes a chain through iff exactly two features meet there without a sharp turn.
  std::vector<char> passes(nv, 0);
  for (int v = 0; v < nv; ++v) {
    if (at[v].empty()) continue;
    if (at[v].size() == 2) {
      const Eigen::Vector3d in = (P.row(v) - P.row(other(at[v][0], v))).transpose();
      const Eigen::Vector3d outv = (P.row(other(at[v][1], v)) - P.row(v)).transpose();
      const double turn = std::atan2(in.cross(outv).norm(), in.dot(outv));
      if (turn <= options.corner_angle * kDegree) {
        passes[v] = 1;
        continue;
      }
    }
    if (at[v].size() != 1) out.corners.push_back(v);
  }

  // Walk chains: first from every vertex that does not pass, then the closed loops that remain.
  std::vector<char> used(edges.num_edges(), 0);
  auto walk = [&](int start, int first_edge) {
    FeatureChain chain;
    chain.vertices.push_back(start);
    int v = start, e = first_edge;
    for (;;) {
      used[e] = 1;
      chain.edges.push_back(e);
      v = other(e, v);
      chain.vertices.push_back(v);
      if (v == start) {
        chain.closed = true;
        break;
      }
      if (!passes[v]) break;
      const int next = at[v][0] == e ? at[v][1] : at[v][0];
      if (used[next]) break;
      e = next;
    }
    out.chains.push_back(std::move(chain));
  };
  for (int v = 0; v < nv; ++v)
    if (!passes[v])
      for (int e : at[v])
        if (!used[e]) walk(v, e);
  for (int e : out.edges)
    if (!used[e]) walk(edges.vertices(e)[0], e);
  return out;
}

GuideLayer feature_band_guide(const TriangleMesh& mesh, const TangentFrames& frames, int n, const MeshEdges& edges,
                              const FeatureSet& features, int width) {
  if (width < 1) throw ParameterError("feature width must be at least 1 edge ring, got " + std::to_string(width));
  GuideAccumulator acc(mesh.num_faces());
  FaceWalker walker(mesh);
  std::vector<int> seeds;
  for (const FeatureChain& chain : features.chains)
    for (std::size_t i = 0; i < chain.edges.size(); ++i) {
      const int e = chain.edges[i];
      const Eigen::Vector3d v = chain_edge_vector(mesh, chain, i);
      seeds.clear();
      for (int k = 0; k < edges.num_faces(e); ++k) seeds.push_back(edges.face(e, k));
      walker.rings(seeds, width, [&](int f, int ring) {
        const double w = 1.0 - static_cast<double>(ring - 1) / width;
        acc.add(f, unit_representation(frames, f, v, n), w);
      });
    }
  return acc.finish();
}

std::vector<HardDirection> feature_hard_directions(const TriangleMesh& mesh, const TangentFrames& frames, int n,
                                                   const MeshEdges& edges, const FeatureSet& features, int every) {
  if (every < 1) throw ParameterError("'every' must be at least 1 (every k-th feature edge), got " + std::to_string(every));
  std::vector<HardDirection> out;
  for (std::size_t c = 0; c < features.chains.size(); ++c) {
    const FeatureChain& chain = features.chains[c];
    for (std::size_t i = 0; i < chain.edges.size(); i += static_cast<std::size_t>(every)) {
      const int e = chain.edges[i];
      const Eigen::Vector3d v = chain_edge_vector(mesh, chain, i);
      for (int k = 0; k < edges.num_faces(e); ++k) {
        const int f = edges.face(e, k);
        const Complex d = unit_representation(frames, f, v, n);
        if (std::abs(d) > 0) out.push_back({f, d, static_cast<int>(c)});
      }
    }
  }
  return out;
}

}  // namespace nfield
