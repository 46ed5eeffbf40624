// Cuts (discontinuity edges): the surface cut open along chosen edges, so that the field may jump there.
//
// The solver already treats boundary and non-manifold edges as cuts: no energy couples the faces on the two
// sides. cut_mesh() makes any chosen interior edge behave the same way by cutting the mesh open along it:
// the corners of the faces around each vertex are grouped into the fans that stay connected through uncut
// edges, and every fan but the first gets its own copy of the vertex (same position). Faces, their order,
// their vertex order and every vertex position are kept, so face frames, areas and normals are bit-identical
// to the input mesh's and a field, a guide or a constraint means the same thing on both meshes; vertices
// on the cuts get copies numbered from num_vertices() on, so every other vertex keeps its index.
// Downstream everything follows from the mesh: the dual graph has no edge across a cut, a vertex on a cut
// is a boundary vertex (no singularity index, no singularity constraint), and a cut that separates a piece
// makes it a component of its own.
// One case cannot open: an isolated single cut edge whose two ends are both inside the surface (each end's
// fan stays connected around it). Such edges are reported, not cut.
#pragma once
#include <array>
#include <memory>
#include <vector>

#include "nfield/mesh_edges.hpp"

namespace nfield {

struct CutMesh {
  std::shared_ptr<const TriangleMesh> mesh;  ///< the mesh cut open (same faces, more vertices)
  std::vector<int> vertex_origin;            ///< per vertex of `mesh`: the input vertex it copies
  int num_cut = 0;                           ///< interior edges opened
  std::vector<std::array<int, 2>> unopened;  ///< isolated single interior edges (both ends inside)
  std::vector<std::array<int, 2>> already_cut;  ///< boundary or non-manifold edges (nothing to do)
};

/// `cuts`: vertex pairs of edges of active faces (any order; InputError naming those that are not edges).
CutMesh cut_mesh(const TriangleMesh& mesh, const MeshEdges& edges, const std::vector<std::array<int, 2>>& cuts);

}  // namespace nfield
