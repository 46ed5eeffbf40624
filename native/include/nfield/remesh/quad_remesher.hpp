// Quad remeshing driven by a designed cross field: the pipeline of named steps.
//
//   1. cut surface (remesh_surface.hpp): active faces, cut at non-manifold and orientation cuts; components
//      smaller than the target are left out (listed) or refused;
//   2. features: boundary and sharp edges (dihedral angle above a threshold);
//   3. vertex cross field: our face field moved to vertices, n-symmetrically (not optimised);
//   4. hierarchy (multires_hierarchy.hpp) and 4-PoSy position field (position_field.hpp) with spacing s
//      (or, adaptive_spacing, s e^u per vertex following the field's turning: lattice_spacing.hpp);
//   5. extraction (quad_extraction.hpp): clusters, links, faces; manifold and oriented by construction;
//   6. clean-up (quad_cleanup.hpp): doublets and triangle pairs merged, vertices relaxed;
//   7. optional pure quads (pure_quads.hpp): the odd faces paired by paths of faces that are split into
//      half-width quads along the way, at the target edge length (by default steps 4-7 run twice, cones
//      free and cones pinned to lattice points, and the output with fewer irregular vertices is kept:
//      pure_quad_cones); or (subdivide_for_pure_quads) one subdivision step of a lattice twice as coarse,
//      new vertices projected onto the input.
//
// Units: edge_length in mesh units; angles in degrees.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "nfield/mesh.hpp"
#include "nfield/remesh/polygon_mesh.hpp"
#include "nfield/remesh/position_field.hpp"
#include "nfield/remesh/position_singularities.hpp"
#include "nfield/remesh/pure_quads.hpp"
#include "nfield/remesh/quad_cleanup.hpp"
#include "nfield/remesh/far_point_fit.hpp"
#include "nfield/remesh/lattice_spacing.hpp"
#include "nfield/remesh/quad_diagonals.hpp"
#include "nfield/remesh/quad_extraction.hpp"
#include "nfield/remesh/quad_untangle.hpp"

namespace nfield::remesh {

struct QuadRemeshOptions {
  double edge_length = 0;            ///< target edge length of the output (mesh units), > 0
  bool pure_quads = false;           ///< all faces quads (pure_quads.hpp)
  bool subdivide_for_pure_quads = false;  ///< pure quads by one subdivision step of a lattice twice as coarse
  bool keep_boundary = true;         ///< boundary edges are feature curves
  double sharp_angle_degrees = 40;   ///< edges with a larger dihedral angle are feature curves (<= 0: none)
  double feature_field_angle_degrees = 35;  ///< sharp edges further than this from the field are not kept
  std::uint64_t seed = 0;            ///< random lattice origins on the coarsest level
  int iterations = 10;               ///< Gauss-Seidel sweeps per hierarchy level
  int max_face_size = 12;            ///< larger extracted faces are dropped
  int relax_iterations = 2;          ///< relaxation steps after extraction (and after subdivision)
  int field_relax_iterations = 6;    ///< steps of relaxation along the field (field_relaxation.hpp; the last pass: <= 3)
  bool refuse_small_components = false;  ///< true: a component too small for the target is an error
  bool cancel_position_singularities = true;  ///< min-cost flow on the integer offsets (position_singularities.hpp)
  /// Pure quads by pairing only: 1 pins every field singularity to a lattice point (a vertex-centred cone:
  /// one valence-3 or -5 vertex, no odd face to pair), 0 leaves the cones where the position field puts
  /// them, -1 (default) makes both and keeps the one with fewer flipped faces, then fewer irregular
  /// vertices (twice the work; the two run on two threads).
  int pure_quad_cones = -1;
  bool fit_far_points = true;        ///< vertices moved onto input points the output misses (far_point_fit.hpp)
  bool split_thin_clusters = true;   ///< clusters wrapped round a thin part split per side (quad_extraction.hpp)
  /// The lattice spacing follows the field's turning (lattice_spacing.hpp: edge_length e^u per vertex, u the
  /// conformal scale, the mean face area kept) instead of edge_length everywhere. Not with
  /// subdivide_for_pure_quads (its lattice twice as coarse keeps one spacing).
  bool adaptive_spacing = true;
  double max_spacing_ratio = 1.6;    ///< adaptive spacing within [edge_length / ratio, edge_length ratio], 1..4
};

struct QuadRemeshResult {
  PolygonMesh mesh;
  std::vector<char> vertex_feature_kind;  ///< FeatureKind of each output vertex
  std::vector<std::string> messages;      ///< what was skipped or repaired, one line each
  int num_components = 0, remeshed_components = 0;
  int num_levels = 0;
  int num_boundary_feature_edges = 0, num_sharp_feature_edges = 0;
  int num_vertices_without_field = 0;
  double lattice_spacing = 0;
  LatticeSpacingReport spacing;           ///< the adaptive spacing's range (ratios 1 when off)
  ExtractionReport extraction;
  CleanupReport cleanup;                  ///< quad_cleanup.hpp
  int cleanup_split_faces = 0;            ///< faces of 6 or more sides split (split_large_faces)
  CancellationReport cancellation;        ///< position singularities before / after the flow
  UntangleReport untangle;                ///< flipped faces before / after the last step
  PureQuadReport pure_quads;              ///< the conversion to pure quads at full resolution
  FarPointFitReport far_points;           ///< vertices moved onto input points the output missed
  int rotated_diagonals = 0;              ///< quads whose first vertex moved to split them nearer the input
  int moved_representatives = 0;          ///< vertices whose lattice point changed in the re-solve
  bool flow_discarded = false;            ///< the flow's offsets changed the topology: extracted without them
  double seconds_setup = 0, seconds_hierarchy = 0, seconds_positions = 0, seconds_flow = 0, seconds_resolve = 0,
         seconds_extraction = 0;  ///< wall-clock seconds per step (flow: offsets + min-cost flow; resolve: position re-solve)
};

/// `triangle_directions`: one 3D tangent direction of the cross field per face of `mesh` (any of the four;
/// zero rows: no field there). ParameterError for a bad option, InputError when nothing can be remeshed
/// (every component smaller than the target, or one of them with refuse_small_components), Cancelled.
QuadRemeshResult quad_remesh(const TriangleMesh& mesh, const std::vector<Vec3>& triangle_directions,
                             const QuadRemeshOptions& options, const Progress& progress = {});

}  // namespace nfield::remesh
