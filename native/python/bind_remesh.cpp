// Binding of the remesh area: the quad remesher and its quality statistics (native/include/nfield/remesh/).
// The heavy call releases the GIL; its progress callback re-acquires it, and returning False (or raising)
// cancels (binding_support.hpp).
#include <array>
#include <climits>
#include <memory>
#include <string>
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
  py::dict d;
  d["clusters"] = r.clusters;
  d["links"] = r.links;
  d["merged_short_links"] = r.merged_short_links;
  d["removed_dangling"] = r.removed_dangling;
  d["split_faces"] = r.split_faces;
  d["dropped_large_faces"] = r.dropped_large_faces;
  d["open_walks"] = r.open_walks;
  d["removed_conflicting"] = r.removed_conflicting;
  d["split_vertices"] = r.split_vertices;
  return d;
}

}  // namespace

void bind_remesh(py::module_& m) {
  m.def("quad_remesh", [](std::shared_ptr<TriangleMesh> mesh, const DoubleArray& directions, double edge_length,
                          bool pure_quads, bool keep_boundary, double sharp_angle, unsigned long long seed,
                          int iterations, int max_face_size, bool refuse_small_components, int relax_iterations,
                          bool cancel_position_singularities, const py::object& progress) {
    const std::vector<Vec3> dirs = to_points(directions, "field directions");
    QuadRemeshOptions o;
    o.edge_length = edge_length;
    o.pure_quads = pure_quads;
    o.keep_boundary = keep_boundary;
    o.sharp_angle_degrees = sharp_angle;
    o.seed = seed;
    o.iterations = iterations;
    o.max_face_size = max_face_size;
    o.refuse_small_components = refuse_small_components;
    o.relax_iterations = relax_iterations;
    o.cancel_position_singularities = cancel_position_singularities;
    const PythonProgress cb = wrap_progress(progress);
    const QuadRemeshResult r =
        run_with_progress(cb, [&] { return without_gil([&] { return quad_remesh(*mesh, dirs, o, cb.callback); }); });
    py::dict d;
    d["vertices"] = from_vec3(r.mesh.positions);
    d["face_offsets"] = from_std(r.mesh.offsets);
    d["face_indices"] = from_std(r.mesh.indices);
    std::vector<int> kind(r.vertex_feature_kind.begin(), r.vertex_feature_kind.end());
    d["vertex_feature_kind"] = from_std(kind);
    d["messages"] = r.messages;
    d["num_components"] = r.num_components;
    d["remeshed_components"] = r.remeshed_components;
    d["num_levels"] = r.num_levels;
    d["num_boundary_feature_edges"] = r.num_boundary_feature_edges;
    d["num_sharp_feature_edges"] = r.num_sharp_feature_edges;
    d["num_vertices_without_field"] = r.num_vertices_without_field;
    d["lattice_spacing"] = r.lattice_spacing;
    d["extraction"] = extraction_dict(r.extraction);
    d["cleanup"] = py::dict(py::arg("doublets") = r.cleanup_doublets, py::arg("triangle_pairs") = r.cleanup_triangle_pairs,
                            py::arg("triangle_strips") = r.cleanup_triangle_strips,
                            py::arg("split_large_faces") = r.cleanup_split_faces);
    const CancellationReport& c = r.cancellation;
    d["position_singularities"] = py::dict(
        py::arg("orientation_singularities") = c.orientation_singularities,
        py::arg("before") = c.position_singularities_before, py::arg("after") = c.position_singularities_after,
        py::arg("folded_before") = c.folded_before, py::arg("routed") = c.routed, py::arg("unrouted") = c.unrouted,
        py::arg("changed_offsets") = c.changed_offsets, py::arg("fixed_offsets") = c.fixed_offsets,
        py::arg("cost") = c.cost, py::arg("moved_representatives") = r.moved_representatives,
        py::arg("phases") = c.phases, py::arg("augmentations") = c.augmentations,
        py::arg("network_triangles") = c.network_triangles, py::arg("seconds_collapse") = c.seconds_collapse,
        py::arg("seconds_network") = c.seconds_network, py::arg("seconds_solve") = c.seconds_solve);
    d["untangle"] = py::dict(py::arg("flipped_before") = r.untangle.flipped_before,
                             py::arg("flipped_after") = r.untangle.flipped_after,
                             py::arg("moved_vertices") = r.untangle.moved_vertices,
                             py::arg("released_features") = r.untangle.released_features, py::arg("rounds") = r.untangle.rounds,
                             py::arg("split_faces") = r.untangle.split_faces);
    py::dict t;
    t["setup"] = r.seconds_setup;
    t["hierarchy"] = r.seconds_hierarchy;
    t["positions"] = r.seconds_positions;
    t["flow"] = r.seconds_flow;
    t["resolve"] = r.seconds_resolve;
    t["extraction"] = r.seconds_extraction;
    d["seconds"] = t;
    return d;
  }, py::arg("mesh"), py::arg("directions"), py::arg("edge_length"), py::arg("pure_quads") = false,
     py::arg("keep_boundary") = true, py::arg("sharp_angle") = 40.0, py::arg("seed") = 0ULL, py::arg("iterations") = 10,
     py::arg("max_face_size") = 12, py::arg("refuse_small_components") = false,
     py::arg("relax_iterations") = 2, py::arg("cancel_position_singularities") = true,
     py::arg("progress") = py::none(),
     "Quad remesh along a cross field given as one 3D direction per face (see nfield/remesh/quad_remesher.hpp)");

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
    ManifoldReport r;
    {
      py::gil_scoped_release release;
      r = check_manifold(pm);
    }
    py::dict d;
    d["nonmanifold_edges"] = r.nonmanifold_edges;
    d["inconsistent_edges"] = r.inconsistent_edges;
    d["nonmanifold_vertices"] = r.nonmanifold_vertices;
    d["faces_with_repeated_vertex"] = r.faces_with_repeated_vertex;
    d["boundary_edges"] = r.boundary_edges;
    d["isolated_vertices"] = r.isolated_vertices;
    d["manifold"] = r.manifold();
    d["oriented"] = r.oriented();
    return d;
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
