// Binding of the remesh area: the quad remesher and its quality statistics (native/include/nfield/remesh/).
// The heavy call releases the GIL; its progress callback re-acquires it, and returning False (or raising)
// cancels (binding_support.hpp).
#include <array>
#include <climits>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include "binding_support.hpp"
#include "nfield/errors.hpp"
#include "nfield/mesh.hpp"
#include "nfield/remesh/min_cost_flow.hpp"
#include "nfield/remesh/quad_remesher.hpp"
#include "nfield/remesh/quad_stats.hpp"

namespace nfield::python {

using namespace nfield::remesh;

namespace {

std::vector<Vec3> to_points(const DoubleArray& a, const char* what) {
  if (a.ndim() != 2 || a.shape(1) != 3) throw InputError(std::string(what) + " must be an array of shape (k, 3)");
  std::vector<Vec3> out(a.shape(0));
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    out[i] = Vec3(a.data()[3 * i], a.data()[3 * i + 1], a.data()[3 * i + 2]);
    if (!out[i].allFinite()) throw InputError(std::string(what) + ": row " + std::to_string(i) + " is not finite");
  }
  return out;
}

std::vector<int> to_ints(const IndexArray& a, const char* what) {
  if (a.ndim() != 1) throw InputError(std::string(what) + " must be a 1-D integer array");
  std::vector<int> out(a.shape(0));
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    const long long x = a.data()[i];
    if (x < INT_MIN || x > INT_MAX) throw InputError(std::string(what) + ": entry " + std::to_string(i) + " is out of range");
    out[i] = static_cast<int>(x);
  }
  return out;
}

PolygonMesh to_polygon_mesh(const DoubleArray& vertices, const IndexArray& offsets, const IndexArray& indices) {
  PolygonMesh m;
  m.positions = to_points(vertices, "vertices");
  m.offsets = to_ints(offsets, "face offsets");
  m.indices = to_ints(indices, "face indices");
  for (size_t f = 0; f + 1 < m.offsets.size(); ++f)
    if (m.offsets[f + 1] < m.offsets[f]) throw InputError("face offsets must be non-decreasing");
  m.validate();
  return m;
}

std::vector<std::array<int, 3>> to_reference_triangles(const IndexArray& a, int num_vertices) {
  if (a.ndim() != 2 || a.shape(1) != 3) throw InputError("reference triangles must be an array of shape (k, 3)");
  std::vector<std::array<int, 3>> out(a.shape(0));
  for (py::ssize_t i = 0; i < a.shape(0); ++i)
    for (int c = 0; c < 3; ++c) {
      const long long x = a.data()[3 * i + c];
      if (x < 0 || x >= num_vertices) throw InputError("reference triangle " + std::to_string(i) + " has a vertex index out of range");
      out[i][c] = static_cast<int>(x);
    }
  return out;
}

py::dict extraction_dict(const ExtractionReport& r) {
  return named("clusters", r.clusters, "links", r.links, "merged_short_links", r.merged_short_links,
               "split_clusters", r.split_clusters, "removed_dangling", r.removed_dangling, "split_faces", r.split_faces, "dropped_large_faces",
               r.dropped_large_faces, "open_walks", r.open_walks, "removed_conflicting", r.removed_conflicting,
               "dropped_scraps", r.dropped_scraps, "split_vertices", r.split_vertices);
}

/// The remesher's options from keyword arguments: each name sets the QuadRemeshOptions member of that name
/// (options not given keep the struct's defaults); an unknown name is refused.
QuadRemeshOptions remesh_options(const py::kwargs& kwargs) {
  using O = QuadRemeshOptions;
  using Member = std::variant<double O::*, bool O::*, int O::*, std::uint64_t O::*>;
  static const std::map<std::string, Member> members = {
      {"edge_length", &O::edge_length}, {"pure_quads", &O::pure_quads},
      {"subdivide_for_pure_quads", &O::subdivide_for_pure_quads}, {"keep_boundary", &O::keep_boundary},
      {"sharp_angle", &O::sharp_angle_degrees}, {"feature_field_angle", &O::feature_field_angle_degrees},
      {"seed", &O::seed}, {"iterations", &O::iterations}, {"max_face_size", &O::max_face_size},
      {"relax_iterations", &O::relax_iterations},
      {"field_relax_iterations", &O::field_relax_iterations}, {"refuse_small_components", &O::refuse_small_components},
      {"cancel_position_singularities", &O::cancel_position_singularities},
      {"pure_quad_cones", &O::pure_quad_cones},
      {"fit_far_points", &O::fit_far_points}, {"split_thin_clusters", &O::split_thin_clusters},
      {"adaptive_spacing", &O::adaptive_spacing}, {"max_spacing_ratio", &O::max_spacing_ratio}};
  O o;
  for (const auto& [key, value] : kwargs) {
    const std::string name = py::cast<std::string>(key);
    auto it = members.find(name);
    if (it == members.end()) throw ParameterError("quad_remesh: unknown option '" + name + "'");
    std::visit([&](auto member) { o.*member = py::cast<std::remove_reference_t<decltype(o.*member)>>(value); },
               it->second);
  }
  return o;
}

}  // namespace

void bind_remesh(py::module_& m) {
  m.def("quad_remesh", [](std::shared_ptr<TriangleMesh> mesh, const DoubleArray& directions,
                          const py::object& progress, const py::kwargs& kwargs) {
    const std::vector<Vec3> dirs = to_points(directions, "field directions");
    const QuadRemeshOptions o = remesh_options(kwargs);
    const PythonProgress cb = wrap_progress(progress);
    const QuadRemeshResult r =
        run_with_progress(cb, [&] { return without_gil([&] { return quad_remesh(*mesh, dirs, o, cb.callback); }); });
    py::dict d;
    d["vertices"] = from_vec3(r.mesh.positions);
    d["face_offsets"] = from_std(r.mesh.offsets);
    d["face_indices"] = from_std(r.mesh.indices);
    d["vertex_feature_kind"] = from_std(std::vector<int>(r.vertex_feature_kind.begin(), r.vertex_feature_kind.end()));
    d["messages"] = r.messages;
    d["num_components"] = r.num_components;
    d["remeshed_components"] = r.remeshed_components;
    d["num_levels"] = r.num_levels;
    d["num_boundary_feature_edges"] = r.num_boundary_feature_edges;
    d["num_sharp_feature_edges"] = r.num_sharp_feature_edges;
    d["num_vertices_without_field"] = r.num_vertices_without_field;
    d["lattice_spacing"] = r.lattice_spacing;
    d["adaptive_spacing"] = named("min_ratio", r.spacing.min_ratio, "max_ratio", r.spacing.max_ratio, "clamped_area",
                                  r.spacing.clamped_area, "singular_triangles", r.spacing.singular_triangles, "added_vertices", r.spacing.added_vertices,
                                  "seconds", r.spacing.seconds);
    d["extraction"] = extraction_dict(r.extraction);
    const CleanupReport& k = r.cleanup;
    d["cleanup"] = named("doublets", k.doublets, "triangle_pairs", k.triangle_pairs + k.triangle_pentagon_pairs,
                         "triangle_strips", k.triangle_strips, "split_cones", k.split_cones, "merged_cones",
                         k.merged_cones, "lowered_irregularity", k.lowered_irregularity, "split_large_faces",
                         r.cleanup_split_faces);
    const CancellationReport& c = r.cancellation;
    d["position_singularities"] = named(
        "orientation_singularities", c.orientation_singularities, "before", c.position_singularities_before, "after",
        c.position_singularities_after, "folded_before", c.folded_before, "routed", c.routed, "unrouted", c.unrouted,
        "changed_offsets", c.changed_offsets, "fixed_offsets", c.fixed_offsets, "cost", c.cost,
        "moved_representatives", r.moved_representatives, "phases", c.phases, "augmentations", c.augmentations,
        "network_triangles", c.network_triangles, "seconds_collapse", c.seconds_collapse, "seconds_network",
        c.seconds_network, "seconds_solve", c.seconds_solve);
    const UntangleReport& u = r.untangle;
    d["untangle"] = named("flipped_before", u.flipped_before, "flipped_after", u.flipped_after, "moved_vertices",
                          u.moved_vertices, "released_features", u.released_features, "rounds", u.rounds,
                          "split_faces", u.split_faces, "removed_doublets", u.removed_doublets,
                          "collapsed_edges", u.collapsed_edges, "dropped_scraps", u.dropped_scraps);
    const PureQuadReport& pq = r.pure_quads;
    d["pure_quads"] = named("odd_faces", pq.odd_faces, "paths", pq.paths, "boundary_paths", pq.boundary_paths,
                            "merged_ends", pq.merged_ends, "midpoints", pq.midpoints, "centres", pq.centres,
                            "unpaired", pq.unpaired, "rounds", pq.rounds, "pinned_cones", pq.pinned_cones,
                            "cones_tried", pq.cones_tried, "irregular_free_cones", pq.irregular_free_cones,
                            "irregular_pinned_cones", pq.irregular_pinned_cones);
    const FarPointFitReport& fp = r.far_points;
    d["far_points"] = named("passes", fp.passes, "moves", fp.moves, "pair_moves", fp.pair_moves, "farthest_before",
                            fp.farthest_before, "farthest_after", fp.farthest_after, "seconds", fp.seconds);
    d["rotated_diagonals"] = r.rotated_diagonals;
    d["seconds"] = named("setup", r.seconds_setup, "hierarchy", r.seconds_hierarchy, "positions", r.seconds_positions,
                         "flow", r.seconds_flow, "resolve", r.seconds_resolve, "extraction", r.seconds_extraction);
    return d;
  }, py::arg("mesh"), py::arg("directions"), py::arg("progress") = py::none(),
     "Quad remesh along a cross field given as one 3D direction per face; options by keyword, named as the "
     "members of QuadRemeshOptions (edge_length, pure_quads, subdivide_for_pure_quads, keep_boundary, sharp_angle, feature_field_angle, "
     "seed, iterations, max_face_size, relax_iterations, refuse_small_components, cancel_position_singularities, pure_quad_cones, fit_far_points, "
     "split_thin_clusters, adaptive_spacing, max_spacing_ratio; "
     "see nfield/remesh/quad_remesher.hpp)");

  m.def("min_cost_flow", [](int num_nodes, const IndexArray& tails, const IndexArray& heads, const IndexArray& capacities,
                            const DoubleArray& costs, const IndexArray& supplies) {
    const std::vector<int> t = to_ints(tails, "tails"), h = to_ints(heads, "heads"), u = to_ints(capacities, "capacities");
    const std::vector<int> b = to_ints(supplies, "supplies");
    if (costs.ndim() != 1) throw InputError("costs must be a 1-D array");
    if (h.size() != t.size() || u.size() != t.size() || static_cast<size_t>(costs.shape(0)) != t.size())
      throw InputError("tails, heads, capacities and costs must have the same length");
    if (num_nodes < 0 || b.size() != static_cast<size_t>(num_nodes)) throw InputError("supplies must have one entry per node");
    MinCostFlow f(num_nodes);
    for (size_t a = 0; a < t.size(); ++a) f.add_arc(t[a], h[a], u[a], costs.data()[a]);
    for (int v = 0; v < num_nodes; ++v) f.add_supply(v, b[v]);
    const MinCostFlow::Result r = without_gil([&] { return f.solve(); });
    std::vector<int> x(t.size());
    for (size_t a = 0; a < t.size(); ++a) x[a] = f.flow(static_cast<int>(a));
    py::dict d;
    d["flow"] = from_std(x);
    d["routed"] = r.routed;
    d["unrouted"] = r.unrouted;
    d["cost"] = r.cost;
    return d;
  }, py::arg("num_nodes"), py::arg("tails"), py::arg("heads"), py::arg("capacities"), py::arg("costs"),
     py::arg("supplies"),
     "Minimum-cost flow by successive shortest paths (nfield/remesh/min_cost_flow.hpp): routes as many supply "
     "units (supplies > 0) to demand nodes (supplies < 0) as possible at least cost; costs >= 0");

  m.def("polygon_manifold_report", [](const DoubleArray& V, const IndexArray& offsets, const IndexArray& indices) {
    const PolygonMesh pm = to_polygon_mesh(V, offsets, indices);
    const ManifoldReport r = without_gil([&] { return check_manifold(pm); });
    return named("nonmanifold_edges", r.nonmanifold_edges, "inconsistent_edges", r.inconsistent_edges,
                 "nonmanifold_vertices", r.nonmanifold_vertices, "faces_with_repeated_vertex",
                 r.faces_with_repeated_vertex, "boundary_edges", r.boundary_edges, "isolated_vertices",
                 r.isolated_vertices, "manifold", r.manifold(), "oriented", r.oriented());
  }, py::arg("vertices"), py::arg("face_offsets"), py::arg("face_indices"));

  m.def("polygon_irregular_vertices", [](const DoubleArray& V, const IndexArray& offsets, const IndexArray& indices) {
    const PolygonMesh pm = to_polygon_mesh(V, offsets, indices);
    IrregularVertices r;
    VertexValence vv;
    {
      py::gil_scoped_release release;
      r = irregular_vertices(pm);
      vv = vertex_valences(pm);
    }
    std::vector<int> boundary(vv.boundary.begin(), vv.boundary.end());
    return py::make_tuple(from_std(r.interior), from_std(r.boundary), from_std(vv.valence),
                          from_std(boundary));
  }, py::arg("vertices"), py::arg("face_offsets"), py::arg("face_indices"),
     "(irregular interior vertices, irregular boundary vertices, valence per vertex, boundary flag per vertex)");

  m.def("polygon_quality", [](const DoubleArray& V, const IndexArray& offsets, const IndexArray& indices,
                              const DoubleArray& ref_vertices, const IndexArray& ref_triangles,
                              const py::object& ref_directions) {
    const PolygonMesh pm = to_polygon_mesh(V, offsets, indices);
    const std::vector<Vec3> rv = to_points(ref_vertices, "reference vertices");
    const auto rt = to_reference_triangles(ref_triangles, static_cast<int>(rv.size()));
    std::vector<Vec3> rd;
    if (!ref_directions.is_none()) {
      rd = to_points(ref_directions.cast<DoubleArray>(), "reference directions");
      if (rd.size() != rt.size()) throw InputError("reference directions must have one row per reference triangle");
    }
    std::vector<double> jac, align;
    double forward = 0, hausdorff = 0;
    std::vector<std::array<int, 2>> edges;
    {
      py::gil_scoped_release release;
      const ReferenceSurface ref = make_reference(rv, rt, rd);
      jac = scaled_jacobians(pm, &ref);
      if (!rd.empty()) align = edge_alignment_degrees(pm, ref);
      edges = unique_edges(pm);
      forward = one_sided_distance(pm, ref.tree);
      hausdorff = hausdorff_distance(pm, ref);
    }
    py::array_t<int> e({static_cast<py::ssize_t>(edges.size()), py::ssize_t(2)});
    for (size_t i = 0; i < edges.size(); ++i) {
      e.mutable_data()[2 * i] = edges[i][0];
      e.mutable_data()[2 * i + 1] = edges[i][1];
    }
    py::dict d;
    d["scaled_jacobians"] = from_std(jac);
    d["edges"] = e;
    d["edge_alignment_degrees"] = rd.empty() ? py::object(py::none()) : py::object(from_std(align));
    d["distance_to_reference"] = forward;
    d["hausdorff"] = hausdorff;
    return d;
  }, py::arg("vertices"), py::arg("face_offsets"), py::arg("face_indices"), py::arg("ref_vertices"),
     py::arg("ref_triangles"), py::arg("ref_directions") = py::none(),
     "Scaled Jacobian per face, edge alignment per unique edge (degrees) and Hausdorff distance (mesh units) "
     "against a reference triangle surface (see nfield/remesh/quad_stats.hpp)");
}

}  // namespace nfield::python
