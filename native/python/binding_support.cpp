#include "binding_support.hpp"

#include <climits>
#include <string>

namespace nfield::python {

void require_shape(const py::array& a, py::ssize_t cols, const char* what) {
  if (a.ndim() != 2 || a.shape(1) != cols)
    throw InputError(std::string(what) + " must be an array of shape (k, " + std::to_string(cols) + "), got " +
                     std::to_string(a.ndim()) + " dimension(s)" +
                     (a.ndim() >= 2 ? " with " + std::to_string(a.shape(1)) + " columns" : std::string()));
}

Positions to_positions(const DoubleArray& a) {
  require_shape(a, 3, "vertex positions");
  Positions P(a.shape(0), 3);
  std::copy(a.data(), a.data() + a.size(), P.data());
  return P;
}

Triangles to_triangles(const IndexArray& a, const char* what) {
  require_shape(a, 3, what);
  Triangles T(a.shape(0), 3);
  const long long* d = a.data();
  for (py::ssize_t i = 0; i < a.size(); ++i) {
    if (d[i] < INT_MIN || d[i] > INT_MAX)
      throw InputError(std::string(what) + ": face " + std::to_string(i / 3) + " has vertex index " +
                       std::to_string(d[i]) + ", which is out of range");
    T.data()[i] = static_cast<int>(d[i]);
  }
  return T;
}

ComplexVector to_complex_vector(const ComplexArray& a, const char* what) {
  if (a.ndim() != 1) throw InputError(std::string(what) + " must be a 1-D complex array");
  return Eigen::Map<const ComplexVector>(a.data(), a.shape(0));
}

ComplexVector optional_alignment(const py::object& alignment) {
  if (alignment.is_none()) return {};
  return to_complex_vector(alignment.cast<ComplexArray>(), "alignment");
}

py::array_t<std::complex<double>> from_complex(const ComplexVector& v) {
  py::array_t<std::complex<double>> out(v.size());
  std::copy(v.data(), v.data() + v.size(), out.mutable_data());
  return out;
}

py::array_t<double> from_eigen(const Eigen::VectorXd& v) {
  py::array_t<double> out(v.size());
  std::copy(v.data(), v.data() + v.size(), out.mutable_data());
  return out;
}

py::array_t<double> from_vec3(const std::vector<Eigen::Vector3d>& v) {
  py::array_t<double> out({static_cast<py::ssize_t>(v.size()), py::ssize_t(3)});
  double* d = out.mutable_data();
  for (size_t i = 0; i < v.size(); ++i)
    for (int c = 0; c < 3; ++c) d[3 * i + c] = v[i][c];
  return out;
}

PythonProgress wrap_progress(const py::object& callable) {
  PythonProgress p;
  if (callable.is_none()) return p;
  auto error = p.error;
  p.callback = [callable, error](double fraction) -> bool {
    py::gil_scoped_acquire gil;
    try {
      py::object r = callable(fraction);
      return r.is_none() || r.cast<bool>();
    } catch (py::error_already_set& e) {
      error->emplace(std::move(e));
      return false;
    } catch (const py::cast_error&) {
      error->emplace(py::error_already_set([] {
        PyErr_SetString(PyExc_TypeError, "progress callback must return a bool or None");
        return py::error_already_set();
      }()));
      return false;
    }
  };
  return p;
}

}  // namespace nfield::python
