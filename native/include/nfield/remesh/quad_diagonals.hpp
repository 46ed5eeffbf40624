// The diagonal that carries a quad's surface.
//
// Four points off one plane bound no single surface: whoever draws or measures a quad splits it into two
// triangles, and the usual split (Blender's tessellation, the fan triangulation of quad_stats.hpp and of
// every OBJ reader that fans from the first vertex) runs along the diagonal from the face's first vertex
// (corners 0-2). Where a quad spans a rounded edge of the input, one diagonal runs along the edge and keeps
// the surface on it, the other cuts across as a chord (rocker arm at 5,000 faces: 0.42 against 0.14 lattice
// steps from the input at a fillet). Choosing the first vertex chooses the diagonal, without moving a
// vertex or changing a face: the faces, valences and edges (so the alignment) stay as they are.
#pragma once
#include "nfield/remesh/polygon_mesh.hpp"
#include "nfield/remesh/triangle_tree.hpp"

namespace nfield::remesh {

/// For every quad, the misfit of each diagonal d: the largest distance of d's midpoint and of the centroids
/// of the two triangles d makes to `surface`, and of the vertices of `surface` nearest to this quad (among
/// all output faces) to those two triangles (mesh units). So neither side of the Hausdorff distance can grow
/// at a vertex: a point nearest to another face keeps its distance, one nearest to this face is counted. A
/// quad whose other diagonal's misfit is lower by more than `margin` (mesh units: no churn between two
/// equally good splits of a flat quad) is rotated by one corner, so that its first vertex starts that
/// diagonal. Returns the number of quads rotated.
int choose_quad_diagonals(PolygonMesh& mesh, const TriangleTree& surface, double margin);

}  // namespace nfield::remesh
