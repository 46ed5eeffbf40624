#include "nfield/remesh/quad_remesher.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <optional>
#include <sstream>
#include <thread>
#include <utility>

#include "nfield/errors.hpp"
#include "nfield/remesh/field_relaxation.hpp"
#include "nfield/remesh/lattice_offsets.hpp"
#include "nfield/remesh/lattice_spacing.hpp"
#include "nfield/remesh/multires_hierarchy.hpp"
#include "nfield/remesh/position_singularities.hpp"
#include "nfield/remesh/irregularity_moves.hpp"
#include "nfield/remesh/quad_cleanup.hpp"
#include "nfield/remesh/quad_stats.hpp"
#include "nfield/remesh/quad_untangle.hpp"
#include "nfield/remesh/remesh_surface.hpp"

namespace nfield::remesh {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::string format(double x) {
  std::ostringstream os;
  os.precision(4);
  os << x;
  return os.str();
}

/// A component can hold a quad mesh of spacing s when its area is at least a few quads and it is not
/// thinner than one quad: area >= 3 s^2 and bounding-box diagonal >= 2 s.
/// Largest lattice (about the output face count) accepted: 2 million faces need about 2 GB on the way.
constexpr double kMaxLatticePoints = 2e6;

/// Euler characteristic V - E + F of a polygon mesh (vertices used by a face only).
long long euler_characteristic(const PolygonMesh& m) {
  std::vector<char> used(m.num_vertices(), 0);
  std::vector<std::pair<int, int>> edges;
  edges.reserve(m.indices.size());
  for (int f = 0; f < m.num_faces(); ++f) {
    const int* v = m.face(f);
    const int k = m.face_size(f);
    for (int i = 0; i < k; ++i) {
      used[v[i]] = 1;
      edges.emplace_back(std::min(v[i], v[(i + 1) % k]), std::max(v[i], v[(i + 1) % k]));
    }
  }
  std::sort(edges.begin(), edges.end());
  const long long E = std::unique(edges.begin(), edges.end()) - edges.begin();
  return std::count(used.begin(), used.end(), 1) - E + m.num_faces();
}

/// Euler characteristic of the triangulated surface the remesher works on.
long long euler_characteristic(const RemeshSurface& s) {
  return static_cast<long long>(s.num_vertices()) - static_cast<long long>(s.edges.size()) +
         static_cast<long long>(s.triangles.size());
}

/// untangle_flipped_faces; then, when `change_faces`, for faces still flipped their valence-2 vertices
/// (feature corners too) removed and split_flipped_faces, each followed by one more untangle. Unused
/// vertices are dropped at the end (kind follows).
UntangleReport untangle(PolygonMesh& mesh, std::vector<char>& kind, const ProjectionTargets& targets, bool change_faces,
                        double spacing, double poor = 0) {
  int collapsed = 0;
  if (change_faces) {
    // Vertices that landed on one point (two lattice points projected onto the tip of a part thinner than a
    // face) are one vertex: no move can open a face whose corners all sit there.
    std::vector<int> into;
    collapsed = collapse_short_edges(mesh, 0.02 * spacing, &into);
    if (collapsed) {
      std::vector<char> merged_kind(into.size(), kNoFeature);
      for (size_t v = 0; v < into.size(); ++v) {
        const char k = v < kind.size() ? kind[v] : kind[into[v]];
        merged_kind[v] = k;
        merged_kind[into[v]] = std::max(merged_kind[into[v]], k);
      }
      kind = std::move(merged_kind);
    }
  }
  UntangleReport r = untangle_flipped_faces(mesh, kind, targets);
  r.collapsed_edges = collapsed;
  auto again = [&]() {
    const UntangleReport more = untangle_flipped_faces(mesh, kind, targets);
    r.flipped_after = more.flipped_after;
    r.moved_vertices += more.moved_vertices;
    r.released_features += more.released_features;
    r.rounds += more.rounds;
  };
  const std::vector<double> jac = change_faces ? scaled_jacobians_on(mesh, targets) : std::vector<double>();
  const bool any_poor = std::any_of(jac.begin(), jac.end(), [&](double q) { return q <= poor; });
  if (change_faces && any_poor) {
    std::vector<char> at_flipped(mesh.num_vertices(), 0);
    for (int f = 0; f < mesh.num_faces(); ++f)
      if (jac[f] <= poor)
        for (int i = 0; i < mesh.face_size(f); ++i) at_flipped[mesh.face(f)[i]] = 1;
    r.removed_doublets = remove_doublets_at(mesh, kind, at_flipped);
    if (r.removed_doublets) again();
  }
  if (change_faces && (r.flipped_after || poor > 0)) {
    r.split_faces = split_flipped_faces(mesh, targets, poor);
    if (r.split_faces) again();
  }
  if (change_faces) r.dropped_scraps = remove_small_pieces(mesh, 4);  // left by the merges and collapses
  const std::vector<int> old = compact_vertices(mesh);
  std::vector<char> compact_kind(old.size());
  for (size_t i = 0; i < old.size(); ++i) compact_kind[i] = kind[old[i]];
  kind = std::move(compact_kind);
  return r;
}

/// Projects the vertices from `first` on onto the input (project_vertices); the others stay where they are.
void project_new_vertices(PolygonMesh& mesh, const std::vector<char>& kind, const ProjectionTargets& targets, int first) {
  std::vector<char> project_kind = kind;
  std::fill(project_kind.begin(), project_kind.begin() + first, kNoFeature);
  const std::vector<Vec3> kept(mesh.positions.begin(), mesh.positions.begin() + first);
  project_vertices(mesh, project_kind, targets);
  std::copy(kept.begin(), kept.end(), mesh.positions.begin());
}

void accumulate(PureQuadReport& total, const PureQuadReport& r) {
  if (total.rounds == 0 && total.paths == 0) total.odd_faces = r.odd_faces;  // the first round's count
  total.paths += r.paths;
  total.boundary_paths += r.boundary_paths;
  total.merged_ends += r.merged_ends;
  total.midpoints += r.midpoints;
  total.centres += r.centres;
  total.unpaired = r.unpaired;
}

/// quad_cleanup's lower_irregularity, then the vertices of the faces it made projected onto the input (the
/// merged ones sit at a midpoint). Not relaxed: a relaxation here pulls them towards the creases they sit
/// next to (fandisk: a face across a concave crease, Hausdorff 0.30 -> 0.39%); step 10 evens them out along
/// the field. Returns the number of moves.
int lower_irregularity_and_project(PolygonMesh& mesh, std::vector<char>& kind, const ProjectionTargets& targets) {
  std::vector<char> changed;
  const int moves = lower_irregularity(mesh, kind, 0.2, 8, &changed);
  if (!moves) return 0;
  const std::vector<int> old = compact_vertices(mesh);
  std::vector<char> compact_kind(old.size());
  for (size_t i = 0; i < old.size(); ++i) compact_kind[i] = kind[old[i]];
  kind = std::move(compact_kind);
  const std::vector<Vec3> kept = mesh.positions;
  project_vertices(mesh, kind, targets);
  for (size_t i = 0; i < old.size(); ++i)
    if (!changed[old[i]]) mesh.positions[i] = kept[i];
  return moves;
}

/// Pure quads: pins the lattice point of every field singularity (a triangle whose vertex crosses turn by a
/// non-zero index around it) to the triangle's centroid, as a feature corner's is pinned to the corner. All
/// three vertices then represent the same lattice point, so the extraction makes one output vertex there,
/// of valence 3 or 5 (a vertex-centred cone), instead of a triangle or a pentagon around the cone (a
/// face-centred cone: an odd face the pure-quad pairing must join to another by a path, which adds about
/// two irregular vertices more). Triangles touching a feature vertex or another pinned triangle are left
/// as they are. Returns the number of cones pinned.
int pin_cones_to_lattice_points(const RemeshSurface& surface, HierarchyLevel& L) {
  HierarchyLevel probe = L;
  probe.p = L.v;
  probe.spacing.assign(L.size(), 1.0);  // the turns do not depend on it
  const LatticeOffsets turns = compute_lattice_offsets(surface, probe);
  const FaceDefects defects = face_defects(surface, triangle_edges(surface), turns);
  int pinned = 0;
  for (size_t t = 0; t < surface.triangles.size(); ++t) {
    if (defects.orientation_index[t] == 0) continue;
    const auto& tri = surface.triangles[t];
    if (std::any_of(tri.begin(), tri.end(), [&](int v) { return L.constraint_kind[v] != kNoFeature; })) continue;
    const Vec3 c = (L.v[tri[0]] + L.v[tri[1]] + L.v[tri[2]]) / 3.0;
    for (int v : tri) L.constraint_kind[v] = kCorner, L.constraint_point[v] = c;
    ++pinned;
  }
  return pinned;
}

/// Cone cost of the flow (lattice steps per unit) when the cones are pinned: a free cone absorbs a unit by
/// shifting its centre within the lattice (cost 1); a pinned one cannot move, so a unit it takes bends the
/// lattice around it. 3 measured best of 1, 3, 8 on the benchmark meshes (fertility 91, 83, 83 irregular
/// vertices; rocker arm 86, 69, 79; bunny 154, 151, 140 with a worse armadillo at 8).
constexpr double kPinnedConeCost = 3;

/// How much farther from the input (one-sided, output to input) the pinned-cone output may be and still be
/// kept for its fewer irregular vertices: 10%, about the spread of that distance between seeds.
constexpr double kPinnedDistanceSlack = 1.1;

/// A quad's other diagonal is taken when it fits the input closer by this fraction of the edge length: a flat
/// quad's two splits differ by rounding only, and its face is left as it is.
constexpr double kDiagonalMargin = 0.01;

bool component_fits(double area, double diagonal, double s) { return area >= 3 * s * s && diagonal >= 2 * s; }

void check_options(const QuadRemeshOptions& o) {
  if (!(o.edge_length > 0) || !std::isfinite(o.edge_length))
    throw ParameterError("quad remesh: the target edge length must be a positive number (got " + format(o.edge_length) + ")");
  if (!std::isfinite(o.sharp_angle_degrees) || o.sharp_angle_degrees >= 180)
    throw ParameterError("quad remesh: sharp_angle must be below 180 degrees (<= 0 disables sharp edges)");
  if (o.iterations < 1 || o.iterations > 1000) throw ParameterError("quad remesh: iterations must be in 1..1000");
  if (o.relax_iterations < 0 || o.relax_iterations > 100) throw ParameterError("quad remesh: relax_iterations must be in 0..100");
  if (o.field_relax_iterations < 0 || o.field_relax_iterations > 100)
    throw ParameterError("quad remesh: field_relax_iterations must be in 0..100");
  if (o.max_face_size < 4 || o.max_face_size > 64) throw ParameterError("quad remesh: max_face_size must be in 4..64");
  if (!(o.feature_field_angle_degrees >= 0 && o.feature_field_angle_degrees <= 45))
    throw ParameterError("quad remesh: feature_field_angle must be in 0..45 degrees");
  if (!(o.max_spacing_ratio >= 1 && o.max_spacing_ratio <= 4))
    throw ParameterError("quad remesh: max_spacing_ratio must be in 1..4 (got " + format(o.max_spacing_ratio) + ")");
  if (o.pure_quad_cones < -1 || o.pure_quad_cones > 1)
    throw ParameterError("quad remesh: pure_quad_cones must be -1 (both tried), 0 (free) or 1 (pinned)");
}

/// What steps 1-3 make (and the two pure-quad runs share): the surface, its features, the vertex cross field,
/// the lattice spacing per vertex and the projection targets, with the report fields these steps fill.
struct PreparedSurface {
  QuadRemeshResult head;                 ///< messages, components, feature counts, spacing report, setup seconds
  double s = 0;                          ///< the target lattice spacing
  RemeshSurface surface;
  Features features;
  std::vector<Vec3> vertex_cross;        ///< per surface vertex
  std::vector<double> spacing;           ///< per surface vertex (mesh units)
  ProjectionTargets targets;
  std::vector<Vec3> target_directions;   ///< the field per triangle of targets.surface
};

/// Steps 1-3: the cut surface, its features, the vertex cross field and (adaptive_spacing) the spacing.
PreparedSurface prepare_surface(const TriangleMesh& mesh, const std::vector<Vec3>& triangle_directions,
                                const QuadRemeshOptions& options) {
  if (static_cast<int>(triangle_directions.size()) != mesh.num_faces())
    throw InputError("quad remesh: the field has " + std::to_string(triangle_directions.size()) +
                     " directions but the mesh has " + std::to_string(mesh.num_faces()) + " faces");
  for (size_t f = 0; f < triangle_directions.size(); ++f)
    if (!triangle_directions[f].allFinite())
      throw InputError("quad remesh: the field direction of face " + std::to_string(f) + " is not finite");
  const auto t0 = std::chrono::steady_clock::now();
  PreparedSurface prepared;
  QuadRemeshResult& result = prepared.head;
  const bool subdivide = options.pure_quads && options.subdivide_for_pure_quads;
  const double s = subdivide ? 2 * options.edge_length : options.edge_length;
  result.lattice_spacing = s;

  // 1. Cut surface, restricted to the components that can hold the lattice.
  RemeshSurface full = make_remesh_surface(mesh);
  result.num_components = full.num_components;
  std::vector<char> keep(full.num_components, 0);
  int kept = 0;
  for (int c = 0; c < full.num_components; ++c) {
    keep[c] = component_fits(full.component_area[c], full.component_diagonal[c], s);
    if (keep[c]) {
      ++kept;
      continue;
    }
    const std::string what = "component " + std::to_string(c) + " (" + std::to_string(full.component_triangles[c]) +
                             " triangles, area " + format(full.component_area[c]) + ", size " +
                             format(full.component_diagonal[c]) + ") is too small for the target edge length " +
                             format(options.edge_length) + " (it needs an area of at least " + format(3 * s * s) +
                             " and a size of at least " + format(2 * s) + ")";
    if (options.refuse_small_components) throw InputError("quad remesh: " + what + "; lower the edge length or raise the face count");
    result.messages.push_back(what + ": not remeshed");
  }
  if (kept == 0)
    throw InputError("quad remesh: every component of the mesh is too small for the target edge length " +
                     format(options.edge_length) + " (" + result.messages.front() +
                     "); lower the edge length or raise the face count");
  std::vector<Vec3> directions;
  RemeshSurface& surface = prepared.surface;
  if (kept == full.num_components) {
    surface = std::move(full);
  } else {
    // Rebuild from the kept faces only (a TriangleMesh of the kept faces keeps the cut rules).
    std::vector<int> faces_kept;
    for (size_t t = 0; t < full.triangles.size(); ++t)
      if (keep[full.vertex_component[full.triangles[t][0]]]) faces_kept.push_back(full.source_triangle[t]);
    Triangles T(faces_kept.size(), 3);
    for (size_t k = 0; k < faces_kept.size(); ++k) T.row(k) = mesh.faces().row(faces_kept[k]);
    const TriangleMesh sub(mesh.positions(), T);
    surface = make_remesh_surface(sub);
    for (int& f : surface.source_triangle) f = faces_kept[f];
  }
  result.remeshed_components = kept;
  // Refuse targets whose lattice would be too fine to hold in memory: the lattice has about area / s^2
  // points, and the surface is refined to edges below s / 2 (about 8 area / s^2 vertices).
  double kept_area = 0;
  for (double a : surface.face_areas) kept_area += a;
  const double lattice_points = kept_area / (s * s);
  if (lattice_points > kMaxLatticePoints)
    throw ParameterError("quad remesh: the target edge length " + format(options.edge_length) + " would make about " +
                         format(lattice_points) + " faces; at most " + format(kMaxLatticePoints) +
                         " are supported (raise the edge length or lower the face count)");
  refine_long_edges(surface, 0.5 * s);
  if (mesh.report().nonmanifold_edges.size() || mesh.report().num_orientation_cuts)
    result.messages.push_back("non-manifold or non-orientable edges were cut: they become boundaries of the output");

  // 2. Features (chains shorter than two lattice steps, tiny holes or noise, are not kept) and 3. the vertex
  //    cross field, once more if the lattice spacing refines the surface.
  Features& features = prepared.features;
  int num_sharp = 0, off_field = 0;
  std::vector<Vec3>& vertex_cross = prepared.vertex_cross;
  auto features_and_cross_field = [&]() {
    directions.resize(surface.triangles.size());
    for (size_t t = 0; t < surface.triangles.size(); ++t) directions[t] = triangle_directions[surface.source_triangle[t]];
    features = detect_features(surface, options.keep_boundary, options.sharp_angle_degrees, 2 * s);
    num_sharp = features.num_sharp_edges;
    off_field = keep_features_along_field(surface, features, directions, options.feature_field_angle_degrees, 2 * s);
    vertex_cross = vertex_cross_field(surface, directions, &features, &result.num_vertices_without_field);
  };
  features_and_cross_field();
  std::vector<double>& spacing = prepared.spacing;
  spacing.assign(surface.num_vertices(), s);
  // The projection targets' surface when the spacing refines the surface further: the unrefined one, with its
  // features and field directions (the same geometry and feature curves on fewer points; the far-point fit
  // visits the targets' vertices one by one).
  std::optional<RemeshSurface> target_surface;
  Features target_features;
  std::vector<Vec3> target_directions;
  if (options.adaptive_spacing && !subdivide) {
    // The spacing follows the field's turning (lattice_spacing.hpp); where it is below s the surface is refined
    // further to edges below half the local spacing, the spacing interpolated at the new midpoints. Not for
    // pure quads by subdivision: its lattice of twice the spacing, made finer in places, left flipped faces
    // after the subdivision (test meshes at 1,500 faces: camel head 2, fandisk 4).
    LatticeSpacingOptions so;
    so.max_ratio = options.max_spacing_ratio;
    const std::vector<double> u = conformal_log_scale(surface, vertex_cross, s, so, &result.spacing);
    std::vector<double> limit(u.size());
    for (size_t v = 0; v < u.size(); ++v) limit[v] = 0.5 * s * std::exp(u[v]);
    const int before_refinement = surface.num_vertices();
    RemeshSurface unrefined = surface;
    refine_long_edges(surface, limit);
    result.spacing.added_vertices = surface.num_vertices() - before_refinement;
    spacing.resize(limit.size());
    for (size_t v = 0; v < limit.size(); ++v) spacing[v] = 2 * limit[v];
    if (surface.num_vertices() != before_refinement) {
      target_surface = std::move(unrefined);
      target_features = features;
      target_directions = directions;
      features_and_cross_field();
    }
  }
  if (off_field)
    result.messages.push_back(std::to_string(num_sharp - features.num_sharp_edges) + " of " + std::to_string(num_sharp) +
                              " sharp edges were not kept: the field crosses them at more than " +
                              format(options.feature_field_angle_degrees) + " degrees");
  result.num_boundary_feature_edges = features.num_boundary_edges;
  result.num_sharp_feature_edges = features.num_sharp_edges;
  if (features.num_dropped_chains)
    result.messages.push_back(std::to_string(features.num_dropped_chains) +
                              " feature chain(s) shorter than two lattice steps (small holes or creases) were not kept");

  if (result.num_vertices_without_field)
    result.messages.push_back(std::to_string(result.num_vertices_without_field) +
                              " vertices have no field direction around them (zero field): their edges follow the mesh");
  prepared.s = s;
  prepared.targets = target_surface ? make_projection_targets(*target_surface, target_features)
                                    : make_projection_targets(surface, features);
  prepared.target_directions = target_surface ? std::move(target_directions) : directions;
  result.seconds_setup = seconds_since(t0);
  return prepared;
}

/// Steps 4 on, once; `pin_cones`: pin_cones_to_lattice_points before the position field.
QuadRemeshResult remesh_once(const PreparedSurface& prepared, const QuadRemeshOptions& options, bool pin_cones,
                             const Progress& progress, double* distance_to_input = nullptr) {
  auto t0 = std::chrono::steady_clock::now();
  auto report = [&](double fraction) {
    if (progress && !progress(fraction)) throw Cancelled("quad remeshing cancelled");
  };
  report(0.0);
  QuadRemeshResult result = prepared.head;
  const bool subdivide = options.pure_quads && options.subdivide_for_pure_quads;
  const double s = prepared.s;
  const RemeshSurface& surface = prepared.surface;
  const Features& features = prepared.features;
  const ProjectionTargets& targets = prepared.targets;
  std::vector<HierarchyLevel> levels(1);
  HierarchyLevel& L = levels[0];
  L.q = prepared.vertex_cross;
  L.spacing = prepared.spacing;
  const int V = surface.num_vertices();
  L.v = surface.positions;
  L.n = surface.vertex_normals;
  L.area = surface.vertex_areas;
  L.adjacency_offsets = surface.adjacency_offsets;
  L.adjacency = surface.adjacency;
  L.adjacency_weight.assign(L.adjacency.size(), 1.0);
  L.constraint_kind = features.vertex_kind;
  L.constraint_point = surface.positions;
  L.constraint_dir = features.vertex_tangent;
  for (int v = 0; v < V; ++v)
    if (L.n[v].squaredNorm() == 0) L.n[v] = Vec3::UnitZ();
  if (pin_cones) result.pure_quads.pinned_cones = pin_cones_to_lattice_points(surface, L);
  result.seconds_setup += seconds_since(t0);
  report(0.1);

  // 4. Hierarchy and position field.
  t0 = std::chrono::steady_clock::now();
  build_hierarchy(levels);
  result.num_levels = static_cast<int>(levels.size());
  result.seconds_hierarchy = seconds_since(t0);
  report(0.15);
  t0 = std::chrono::steady_clock::now();
  PositionFieldOptions po;
  po.scale = s;
  po.iterations = options.iterations;
  po.seed = options.seed;
  optimise_positions(levels, po, [&](double f) { return !progress || progress(0.15 + 0.7 * f); });
  result.seconds_positions = seconds_since(t0);

  // 5. Integer offsets; position singularities cancelled by a minimum-cost flow, positions re-solved.
  t0 = std::chrono::steady_clock::now();
  LatticeOffsets offsets = compute_lattice_offsets(surface, levels[0]);
  const LatticeOffsets before = offsets;
  const std::vector<Vec3> optimised_p = levels[0].p;
  bool flow_applied = false;
  if (options.cancel_position_singularities) {
    const auto face_edges = triangle_edges(surface);
    CancellationOptions cancel_options;
    // A pinned cone that absorbs a unit moves the lattice against its pin: dearer than a free cone.
    if (pin_cones) cancel_options.cone_cost = kPinnedConeCost;
    const CancellationReport c = cancel_position_singularities(surface, levels[0], face_edges, features.edge_is_feature,
                                                               offsets, cancel_options, [&]() { return progress && !progress(0.86); });
    report(0.86);
    result.cancellation = c;
    result.seconds_flow = seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    if (c.changed_offsets > 0) {
      const std::vector<Vec3>& old_p = optimised_p;
      if (resolve_positions(surface, levels[0], offsets)) {
        result.moved_representatives = normalize_representatives(surface, levels[0], offsets);
        flow_applied = true;
      } else {
        // The re-solve is a least-squares problem on the changed offsets; when it fails (singular system)
        // the optimised positions and their own offsets are still a valid input to the extraction.
        levels[0].p = old_p;
        offsets = before;
        result.messages.push_back("the position re-solve failed: position singularities were left as they were");
      }
    }
    result.seconds_resolve = seconds_since(t0);
  } else {
    result.seconds_flow = seconds_since(t0);
  }

  // 6. Extraction.
  t0 = std::chrono::steady_clock::now();
  result.mesh = extract_quad_mesh(surface, features, levels[0], offsets, targets, options.max_face_size,
                                  result.extraction, &result.vertex_feature_kind, options.split_thin_clusters);
  const long long surface_chi = euler_characteristic(surface);
  if (flow_applied && euler_characteristic(result.mesh) != surface_chi) {
    // The changed offsets can pinch a thin part (an arm, a finger) at a coarse lattice, which changes the
    // output's topology; the lattice as optimised, without the flow, is tried instead and kept when its
    // topology is closer to the input's.
    ExtractionReport plain_report;
    std::vector<char> plain_kind;
    HierarchyLevel plain = levels[0];
    plain.p = optimised_p;
    PolygonMesh plain_mesh = extract_quad_mesh(surface, features, plain, before, targets, options.max_face_size,
                                               plain_report, &plain_kind, options.split_thin_clusters);
    if (std::llabs(euler_characteristic(plain_mesh) - surface_chi) <
        std::llabs(euler_characteristic(result.mesh) - surface_chi)) {
      result.mesh = std::move(plain_mesh);
      result.vertex_feature_kind = std::move(plain_kind);
      result.extraction = plain_report;
      result.messages.push_back("cancelling the row ends changed the topology of the output (a thin part was "
                                "pinched): extracted without it");
      result.cancellation.position_singularities_after = result.cancellation.position_singularities_before;
      result.cancellation.changed_offsets = 0;
      result.flow_discarded = true;
    }
  }
  const CleanupReport cleanup = clean_up_quads(result.mesh, result.vertex_feature_kind);
  result.cleanup = cleanup;
  result.cleanup_split_faces = split_large_faces(result.mesh, result.vertex_feature_kind, targets);
  relax_vertices(result.mesh, result.vertex_feature_kind, targets, options.relax_iterations);
  // Cones left as clusters of irregular vertices (some made by the large-face splits) are mended on the
  // relaxed mesh, whose corners are fair enough to judge the moves by.
  result.cleanup.lowered_irregularity = lower_irregularity_and_project(result.mesh, result.vertex_feature_kind, targets);
  report(0.95);

  // 7. Pure quads.
  UntangleReport before_subdivision;
  if (options.pure_quads && !subdivide) {
    // At full resolution: the quad-dominant mesh untangled (faces may split), then its odd faces paired.
    // Faces still flipped after that are split (untangle) and paired again, up to twice.
    before_subdivision = untangle(result.mesh, result.vertex_feature_kind, targets, true, s);
    for (int round = 0; round < 3; ++round) {
      const int old_vertices = result.mesh.num_vertices();
      const PureQuadReport r = convert_to_pure_quads(result.mesh, result.vertex_feature_kind, targets);
      accumulate(result.pure_quads, r);
      project_new_vertices(result.mesh, result.vertex_feature_kind, targets, old_vertices);
      // Only the faces the conversion made are relaxed (their flat corners at midpoints open up); the rest
      // was relaxed already, and more steps would slide curve vertices further along their features.
      std::vector<char> movable(result.mesh.num_vertices(), 0);
      for (int f = 0; f < result.mesh.num_faces(); ++f) {
        const int* fv = result.mesh.face(f);
        const int k = result.mesh.face_size(f);
        if (std::none_of(fv, fv + k, [&](int v) { return v >= old_vertices; })) continue;
        for (int i = 0; i < k; ++i) movable[fv[i]] = 1;
      }
      relax_vertices(result.mesh, result.vertex_feature_kind, targets, options.relax_iterations, &movable);
      result.cleanup.lowered_irregularity += lower_irregularity_and_project(result.mesh, result.vertex_feature_kind, targets);
      if (round == 2) break;
      const std::vector<double> jac = scaled_jacobians_on(result.mesh, targets);
      if (std::none_of(jac.begin(), jac.end(), [](double q) { return q <= 0; })) break;
      const UntangleReport u = untangle(result.mesh, result.vertex_feature_kind, targets, true, s);
      before_subdivision.flipped_before += u.flipped_before;
      before_subdivision.moved_vertices += u.moved_vertices;
      before_subdivision.released_features += u.released_features;
      before_subdivision.split_faces += u.split_faces;
      before_subdivision.removed_doublets += u.removed_doublets;
      before_subdivision.collapsed_edges += u.collapsed_edges;
      ++result.pure_quads.rounds;
      if (u.split_faces == 0 && u.collapsed_edges == 0 && u.removed_doublets == 0 && u.dropped_scraps == 0) break;
    }
  } else if (options.pure_quads) {
    before_subdivision = untangle(result.mesh, result.vertex_feature_kind, targets, true, s, 0.05);
    std::vector<int> kind;
    std::vector<std::array<int, 2>> edge_of;
    PolygonMesh fine = subdivide_to_quads(result.mesh, &kind, &edge_of);
    std::vector<char> fkind(fine.num_vertices(), kNoFeature);
    for (int v = 0; v < fine.num_vertices(); ++v) {
      if (kind[v] == 0) fkind[v] = result.vertex_feature_kind[v];
      // A midpoint lies on a feature curve when both ends do (corner or curve) and the edge runs along a
      // feature, not across a band between two of them: its midpoint is near a feature edge.
      else if (kind[v] == 1 && result.vertex_feature_kind[edge_of[v][0]] && result.vertex_feature_kind[edge_of[v][1]] &&
               !targets.feature_edges.empty()) {
        const double length = (fine.positions[edge_of[v][0]] - fine.positions[edge_of[v][1]]).norm();
        if (std::sqrt(targets.feature_edges.closest(fine.positions[v]).squared_distance) < 0.25 * length) fkind[v] = kCurve;
      }
    }
    const int old_vertices = result.mesh.num_vertices();  // subdivide_to_quads numbers the original vertices first
    result.mesh = std::move(fine);
    project_new_vertices(result.mesh, fkind, targets, old_vertices);
    result.vertex_feature_kind = std::move(fkind);
    relax_vertices(result.mesh, result.vertex_feature_kind, targets, options.relax_iterations);
  }
  relax_along_field(result.mesh, result.vertex_feature_kind, targets, prepared.target_directions,
                    options.field_relax_iterations);
  // 8. Guarded last step: vertices of flipped faces moved until none is left (quad_untangle.hpp); faces that
  //    stay flipped split along a diagonal. For pure quads this runs on the quad-dominant mesh before the
  //    subdivision too (a split face still becomes quads there), and after it without splits.
  result.untangle = untangle(result.mesh, result.vertex_feature_kind, targets, !options.pure_quads, s);
  if (options.pure_quads) {
    result.untangle.flipped_before += before_subdivision.flipped_before;
    result.untangle.moved_vertices += before_subdivision.moved_vertices;
    result.untangle.released_features += before_subdivision.released_features;
    result.untangle.split_faces = before_subdivision.split_faces;
    result.untangle.removed_doublets += before_subdivision.removed_doublets;
    result.untangle.collapsed_edges += before_subdivision.collapsed_edges;
  }
  // 9. Vertices moved onto the input points the output misses (far_point_fit.hpp): after the untangling, so
  //    that its guard (no face's worst corner below 0.05 or its own) keeps every face as valid as it was.
  const std::vector<Vec3> before_fit = result.mesh.positions;
  if (options.fit_far_points)
    result.far_points = fit_far_points(result.mesh, result.vertex_feature_kind, targets, options.edge_length,
                                       options.sharp_angle_degrees);
  // 10. The relaxation along the field once more, now that the untangling has mended the faces whose
  //     vertices it held back, the vertices the fit moved held so that the distance they gained stays.
  std::vector<char> fit_moved(result.mesh.num_vertices(), 0);
  for (int v = 0; v < result.mesh.num_vertices(); ++v) fit_moved[v] = result.mesh.positions[v] != before_fit[v];
  refine_along_field(result.mesh, result.vertex_feature_kind, targets, prepared.target_directions, options.field_relax_iterations,
                     fit_moved);
  // 11. Each quad split along its diagonal nearer the input (quad_diagonals.hpp), on the final positions.
  result.rotated_diagonals =
      choose_quad_diagonals(result.mesh, targets.surface, kDiagonalMargin * options.edge_length);
  if (result.untangle.flipped_after)
    result.messages.push_back(std::to_string(result.untangle.flipped_after) +
                              " face(s) are still flipped (a corner turned against the surface): the target is too "
                              "coarse for a part of the mesh; raise the face count");
  result.seconds_extraction = seconds_since(t0);
  if (result.extraction.removed_conflicting)
    result.messages.push_back(std::to_string(result.extraction.removed_conflicting) +
                              " extracted face(s) would have made an edge non-manifold and were left out (holes)");
  if (result.extraction.dropped_large_faces)
    result.messages.push_back(std::to_string(result.extraction.dropped_large_faces) + " extracted face(s) larger than " +
                              std::to_string(options.max_face_size) + " sides were left out (holes)");
  if (result.mesh.num_faces() == 0)
    throw SolverError("quad remesh: the extraction produced no face (is the field zero everywhere?)");
  if (distance_to_input) *distance_to_input = one_sided_distance(result.mesh, targets.surface);
  report(1.0);
  return result;
}


/// quad_remesh for valid options (below).
QuadRemeshResult remesh(const TriangleMesh& mesh, const std::vector<Vec3>& triangle_directions,
                        const QuadRemeshOptions& options, const Progress& progress) {
  const bool paired = options.pure_quads && !options.subdivide_for_pure_quads;
  if (!paired || options.pure_quad_cones >= 0)
    return remesh_once(prepare_surface(mesh, triangle_directions, options), options,
                       paired && options.pure_quad_cones == 1, progress);
  // Pure quads by pairing, cones both ways: which leaves fewer irregular vertices depends on how the cones
  // sit in the lattice (pinned cones end as single vertices but constrain the flow), so both are made. The
  // pinned one is kept when it has no more flipped faces, fewer irregular vertices, and stays as close to the
  // input (its farthest point at most kPinnedDistanceSlack times the free one's: a pinned cone on a thin part
  // can pull a row off the surface, fertility at 1,500 faces 1.0 -> 1.5% of the diagonal); else the free one.
  //
  // The two candidates are independent, so the pinned one runs on a second thread while this thread makes
  // the free one. Progress (the mean of both fractions) and cancellation go through this thread only: the
  // caller's callback may hold an interpreter lock, and is never called from the other thread.
  std::atomic<double> pinned_fraction{0.0};
  std::atomic<bool> stop{false}, pinned_done{false};
  double distance_free = 0, distance_pinned = 0;
  // Steps 1-3 once, read (never written) by both candidates.
  const PreparedSurface prepared = prepare_surface(mesh, triangle_directions, options);
  QuadRemeshResult pinned;
  std::exception_ptr pinned_error;
  std::thread pinned_thread([&] {
    try {
      const Progress pinned_progress = [&](double f) {
        pinned_fraction = f;
        return !stop.load();
      };
      pinned = remesh_once(prepared, options, true, pinned_progress, &distance_pinned);
    } catch (...) {
      pinned_error = std::current_exception();
    }
    pinned_done = true;
  });
  // Joins the second thread before any exit from here, cancelling it first when this thread failed.
  struct JoinPinned {
    std::thread& thread;
    std::atomic<bool>& stop;
    ~JoinPinned() {
      if (thread.joinable()) {
        stop = true;
        thread.join();
      }
    }
  } join_pinned{pinned_thread, stop};
  auto combined = [&](double free_fraction) {
    return !progress || progress(0.5 * (free_fraction + pinned_fraction.load()));
  };
  QuadRemeshResult free_cones =
      remesh_once(prepared, options, false, progress ? Progress(combined) : Progress(), &distance_free);
  while (progress && !pinned_done.load()) {
    // The free candidate is done; keep reporting (and listening for a cancel) while the pinned one ends.
    if (!combined(1.0)) throw Cancelled("quad remeshing cancelled");
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  pinned_thread.join();
  if (pinned_error) std::rethrow_exception(pinned_error);
  auto irregular = [](const QuadRemeshResult& r) {
    const IrregularVertices iv = irregular_vertices(r.mesh);
    return static_cast<int>(iv.interior.size() + iv.boundary.size());
  };
  const int irregular_free = irregular(free_cones), irregular_pinned = irregular(pinned);
  const bool take_pinned = std::make_pair(pinned.untangle.flipped_after, irregular_pinned) <
                               std::make_pair(free_cones.untangle.flipped_after, irregular_free) &&
                           distance_pinned <= kPinnedDistanceSlack * distance_free;
  QuadRemeshResult& kept = take_pinned ? pinned : free_cones;
  kept.pure_quads.cones_tried = pinned.pure_quads.pinned_cones;
  kept.pure_quads.irregular_free_cones = irregular_free;
  kept.pure_quads.irregular_pinned_cones = irregular_pinned;
  if (progress && !progress(1.0)) throw Cancelled("quad remeshing cancelled");
  return std::move(kept);
}

}  // namespace

QuadRemeshResult quad_remesh(const TriangleMesh& mesh, const std::vector<Vec3>& triangle_directions,
                             const QuadRemeshOptions& options, const Progress& progress) {
  check_options(options);
  QuadRemeshResult result = remesh(mesh, triangle_directions, options, progress);
  if (!(options.adaptive_spacing && result.flow_discarded)) return result;
  // The flow's offsets pinched a thin part, so its row ends were all left (2.5-5x the irregular vertices); a
  // spacing up to max_spacing_ratio times larger makes that likelier on thin parts (the armadillo at ratio
  // 1.3, seed 1: 364 irregular vertices). One spacing everywhere is tried then, and kept unless it pinches too.
  QuadRemeshOptions constant = options;
  constant.adaptive_spacing = false;
  QuadRemeshResult retry = remesh(mesh, triangle_directions, constant, progress);
  if (retry.flow_discarded) return result;
  retry.messages.push_back("the adaptive spacing pinched a thin part when the row ends were cancelled: remeshed "
                           "with one spacing");
  return retry;
}

}  // namespace nfield::remesh
