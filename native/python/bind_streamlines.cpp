// Binding of the streamlines area: evenly spaced hatching strokes along a field (streamlines.hpp).
#include <cmath>
#include <limits>

#include "binding_support.hpp"
#include "nfield/streamlines.hpp"

namespace nfield::python {

void bind_streamlines(py::module_& m) {
  m.def("trace_streamlines", [](std::shared_ptr<FieldOperators> ops, const ComplexArray& z, double separation,
                                int family, bool cross_hatch, double max_length, double min_length,
                                unsigned long long seed, const py::object& density, bool density_per_vertex,
                                double test_ratio, double step_ratio, double max_turn, bool stop_at_singularities,
                                double min_density, long long max_total_points) {
    const ComplexVector field = to_complex_vector(z, "field");
    StreamlineParams p;
    p.separation = separation;
    p.family = family;
    p.cross_hatch = cross_hatch;
    p.max_length = max_length;
    p.min_length = min_length;
    p.seed = seed;
    p.test_ratio = test_ratio;
    p.step_ratio = step_ratio;
    p.seed_ratio = std::max(0.9, test_ratio);
    p.max_turn = max_turn;
    p.stop_at_singularities = stop_at_singularities;
    p.min_density = min_density;
    p.max_total_points = max_total_points;
    if (!density.is_none()) {
      const DoubleArray d = density.cast<DoubleArray>();
      if (d.ndim() != 1) throw InputError("density must be a 1-D array");
      p.density.assign(d.data(), d.data() + d.shape(0));
      p.density_per_vertex = density_per_vertex;
    }
    const Streamlines r = without_gil([&] { return trace_streamlines(*ops, field, p); });
    py::list points, faces;
    std::vector<int> families;
    std::vector<double> lengths;
    for (const Stroke& s : r.strokes) {
      points.append(from_vec3(s.points));
      faces.append(from_std(s.faces));
      families.push_back(s.family);
      lengths.push_back(s.length);
    }
    py::dict stats;
    stats["num_points"] = r.stats.num_points;
    stats["num_strokes"] = r.stats.num_strokes;
    stats["num_discarded"] = r.stats.num_discarded;
    stats["num_candidates"] = r.stats.num_candidates;
    stats["num_blocked_faces"] = r.stats.num_blocked_faces;
    stats["num_singularities"] = r.stats.num_singularities;
    stats["truncated"] = r.stats.truncated;
    stats["coverage"] = r.stats.coverage;
    return py::make_tuple(points, faces, from_std(families), from_std(lengths), stats);
  }, py::arg("ops"), py::arg("z"), py::arg("separation"), py::arg("family") = 0, py::arg("cross_hatch") = false,
        py::arg("max_length") = std::numeric_limits<double>::infinity(), py::arg("min_length") = 0.0,
        py::arg("seed") = 0ULL, py::arg("density") = py::none(), py::arg("density_per_vertex") = true,
        py::arg("test_ratio") = 0.5, py::arg("step_ratio") = 0.2, py::arg("max_turn") = M_PI / 4,
        py::arg("stop_at_singularities") = true, py::arg("min_density") = 0.1,
        py::arg("max_total_points") = 5000000LL,
        "Evenly spaced streamlines of a per-face field (see streamlines.hpp): "
        "(points list of (k,3), faces list of (k,), families, lengths, stats dict)");
}

}  // namespace nfield::python
