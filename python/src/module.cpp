// lapmesh._lapmesh: the Python binding of the operations layer (src/operations) on numpy arrays.
//
// Option values are strings checked against the name tables of lapmesh/types.h and their
// defaults are the settings structs' own, so that the module spells every kind as the command
// line does without a list of its own. The GIL is released while the library computes.
#include "operations/arrays.h"
#include "operations/heap.h"
#include "operations/operations.h"

#include <lapmesh/errors.h>
#include <lapmesh/types.h>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/eval.h>
#include <pybind11/stl.h>

#include <cmath>
#include <cstdlib>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace py = pybind11;
using lapmesh_ops::Mesh;

namespace {

using Coordinates = py::array_t<double, py::array::c_style | py::array::forcecast>;
using Indices = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>;

// ---- names ---------------------------------------------------------------------------------

// The Python keyword of a settings field: the same name, but `lambda` is a Python keyword.
std::string spelling(const std::string& parameter) { return parameter == "lambda" ? "lam" : parameter; }

// A suggested value in Python's spelling: True/False, numbers as they are, names quoted.
std::string value_spelling(const std::string& value)
{
  if(value == "true") return "True";
  if(value == "false") return "False";
  char* end = nullptr;
  std::strtod(value.c_str(), &end);
  if(!value.empty() && *end == '\0') return value;
  return "'" + value + "'";
}

template <typename Enum>
Enum enum_arg(const char* parameter, const std::string& name)
{
  if(const auto e = lapmesh::parse<Enum>(name)) return *e;
  throw lapmesh::Parameter_error(parameter, "unknown " + std::string(parameter) + " '" + name + "' (expected one of: " +
                                              lapmesh::name_list<Enum>() + ")");
}

template <typename Enum>
std::string default_name(Enum value)
{
  return lapmesh::to_string(value);
}

// ---- arrays --------------------------------------------------------------------------------

// A numpy array that owns `value` (moved to the heap): no copy of the result.
template <typename Eigen_type>
py::array owning_array(Eigen_type&& value, std::vector<py::ssize_t> shape, std::vector<py::ssize_t> strides)
{
  auto* held = new std::decay_t<Eigen_type>(std::move(value));
  py::capsule owner(held, [](void* p) { delete static_cast<std::decay_t<Eigen_type>*>(p); });
  return py::array_t<double>(std::move(shape), std::move(strides), held->data(), owner);
}

py::array vector_array(Eigen::VectorXd v)
{
  const py::ssize_t n = v.size();
  return owning_array(std::move(v), {n}, {py::ssize_t(sizeof(double))});
}

py::array rows_array(lapmesh::Vertex_vectors P)  // row-major n x 3
{
  const py::ssize_t n = P.rows();
  return owning_array(std::move(P), {n, 3}, {py::ssize_t(3 * sizeof(double)), py::ssize_t(sizeof(double))});
}

py::array matrix_array(Eigen::MatrixXd A)  // column-major: a Fortran-ordered numpy array
{
  const py::ssize_t r = A.rows(), c = A.cols();
  return owning_array(std::move(A), {r, c}, {py::ssize_t(sizeof(double)), py::ssize_t(r * sizeof(double))});
}

// The arrays of a compressed symmetric matrix as CSR arrays, without a copy: its values, indices
// and starts (int32, as Eigen stores them) share one owner, a matrix on the heap that takes S's
// storage by a swap (S is left empty): Eigen 3.4's sparse matrix has no move constructor, so
// std::move would copy it.
std::tuple<py::array, py::array, py::array> csr_arrays(Eigen::SparseMatrix<double>& S)
{
  using StorageIndex = Eigen::SparseMatrix<double>::StorageIndex;
  auto* held = new Eigen::SparseMatrix<double>();
  held->swap(S);
  py::capsule owner(held, [](void* p) { delete static_cast<Eigen::SparseMatrix<double>*>(p); });
  const py::ssize_t n = held->rows(), nnz = held->nonZeros();
  return {py::array_t<double>({nnz}, {py::ssize_t(sizeof(double))}, held->valuePtr(), owner),
          py::array_t<StorageIndex>({nnz}, {py::ssize_t(sizeof(StorageIndex))}, held->innerIndexPtr(), owner),
          py::array_t<StorageIndex>({n + 1}, {py::ssize_t(sizeof(StorageIndex))}, held->outerIndexPtr(), owner)};
}

py::array_t<std::int64_t> faces_array(const lapmesh_ops::Triangles& tris)
{
  py::array_t<std::int64_t> F({py::ssize_t(tris.size()), py::ssize_t(3)});
  auto f = F.mutable_unchecked<2>();
  for(std::size_t i = 0; i < tris.size(); ++i)
    for(int j = 0; j < 3; ++j) f(py::ssize_t(i), j) = std::int64_t(tris[i][j]);
  return F;
}

void require_shape(const py::array& a, const char* name, const char* what)
{
  if(a.ndim() != 2 || a.shape(1) != 3)
    throw py::value_error(std::string(name) + " must be an array of shape (" + what + ", 3), got shape " +
                          py::str(py::getattr(a, "shape")).cast<std::string>());
}

// The warnings of an operation as LapmeshWarning (the GIL held).
void warn(const std::vector<lapmesh_ops::Warning>& warnings, const std::vector<std::string>& notes = {})
{
  py::object category = py::module_::import("lapmesh._lapmesh").attr("LapmeshWarning");
  auto emit = [&](const std::string& text) {
    if(PyErr_WarnEx(category.ptr(), text.c_str(), 2) != 0) throw py::error_already_set();
  };
  for(const auto& w : warnings) {
    std::string text = w.message;
    for(std::size_t i = 0; i < w.suggestions.size(); ++i)
      text += (i == 0 ? " (set " : ", or ") + spelling(w.suggestions[i].parameter) + "=" +
              value_spelling(w.suggestions[i].value) + (i + 1 == w.suggestions.size() ? ")" : "");
    emit(text);
  }
  for(const auto& n : notes) emit(n);
}

std::vector<std::string> warning_texts(const std::vector<lapmesh_ops::Warning>& warnings)
{
  std::vector<std::string> out;
  for(const auto& w : warnings) out.push_back(w.message);
  return out;
}

// An array of Python objects (numbers, say) as float64, by numpy, which raises on an object that
// is not a number; the checks of a float array then apply.
py::array object_array_as_float(const py::array& a)
{
  return py::module_::import("numpy").attr("asarray")(a, "float64");
}

// F as int64. numpy's own cast would truncate a fraction, turn NaN into an arbitrary index and
// wrap unsigned indices above 2^63: an array of floats is taken only when every value is a whole
// number (np.loadtxt gives such arrays), and only integer or float arrays are taken at all.
Indices indices_of(const py::object& F)
{
  py::array a = py::array::ensure(F);
  if(!a) throw py::type_error("F must be an array of shape (m, 3) of integers");
  require_shape(a, "F", "m");
  if(a.dtype().kind() == 'O') a = object_array_as_float(a);
  const char kind = a.dtype().kind();
  if(kind == 'f') {
    const auto d = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
    const double* x = d.data();
    for(py::ssize_t i = 0; i < d.size(); ++i)
      if(!(std::floor(x[i]) == x[i] && std::abs(x[i]) < 0x1p62))
        throw py::value_error("F must hold whole vertex indices: F[" + std::to_string(i / 3) + ", " +
                              std::to_string(i % 3) + "] is " + py::str(py::float_(x[i])).cast<std::string>());
  } else if(kind == 'u') {
    const auto u = py::array_t<std::uint64_t, py::array::c_style | py::array::forcecast>::ensure(a);
    const std::uint64_t* x = u.data();
    for(py::ssize_t i = 0; i < u.size(); ++i)
      if(x[i] > std::uint64_t(std::numeric_limits<std::int64_t>::max()))
        throw py::value_error("F[" + std::to_string(i / 3) + ", " + std::to_string(i % 3) + "] is " +
                              std::to_string(x[i]) + ", beyond any vertex index");
  } else if(kind != 'i') {
    throw py::type_error("F must be an array of shape (m, 3) of integers, got dtype " +
                         py::str(a.dtype()).cast<std::string>());
  }
  return Indices::ensure(a);
}

// `a` as float64, from integer and float arrays only: numpy's cast would drop a complex value's
// imaginary part (with no more than a warning) and read booleans as 0 and 1. `what` begins the
// message of a refusal ("V must be an array of shape (n, 3)").
py::array_t<double, py::array::forcecast> real_array(const py::object& a, const std::string& what)
{
  py::array array = py::array::ensure(a);
  if(!array) throw py::type_error(what + " of numbers");
  if(array.dtype().kind() == 'O') array = object_array_as_float(array);
  const char kind = array.dtype().kind();
  if(kind != 'f' && kind != 'i' && kind != 'u')
    throw py::type_error(what + " of real numbers, got dtype " + py::str(array.dtype()).cast<std::string>());
  return py::array_t<double, py::array::forcecast>::ensure(array);
}

Coordinates coordinates_of(const py::object& V)
{
  Coordinates v = Coordinates::ensure(real_array(V, "V must be an array of shape (n, 3)"));
  require_shape(v, "V", "n");
  return v;
}

// The mesh of (V, F), arrays of coordinates_of() and indices_of(): validated and oriented as a
// file would be (lapmesh_ops::mesh_from_soup). Only the soup is built with the GIL held (it
// reads the arrays).
lapmesh_ops::Loaded_mesh mesh_of(const Coordinates& V, const Indices& F)
{
  lapmesh::io::Polygon_soup soup;
  const auto v = V.unchecked<2>();
  const auto f = F.unchecked<2>();
  soup.points.resize(std::size_t(v.shape(0)));
  for(py::ssize_t i = 0; i < v.shape(0); ++i) soup.points[std::size_t(i)] = {v(i, 0), v(i, 1), v(i, 2)};
  soup.polygons.resize(std::size_t(f.shape(0)));
  for(py::ssize_t i = 0; i < f.shape(0); ++i) {
    auto& p = soup.polygons[std::size_t(i)];
    p.resize(3);
    for(int j = 0; j < 3; ++j) {
      const std::int64_t x = f(i, j);
      if(x < 0)
        throw lapmesh::Mesh_error("face " + std::to_string(i) + " has a negative vertex index (" + std::to_string(x) +
                                    ")",
                                  lapmesh::Mesh_error::Element::face, i);
      p[std::size_t(j)] = std::size_t(x);
    }
  }
  lapmesh_ops::Loaded_mesh loaded;
  {
    py::gil_scoped_release release;
    loaded = lapmesh_ops::mesh_from_soup(soup);
  }
  warn({}, loaded.notes);
  return loaded;
}

// A validated mesh kept between calls (lapmesh.Mesh): the functions take it instead of (V, F)
// and skip the conversion and validation of the arrays.
struct Validated_mesh
{
  std::shared_ptr<const Mesh> mesh;
};

// The mesh of the arguments (V, F), or V when it is a lapmesh.Mesh (F then None).
std::shared_ptr<const Mesh> mesh_arg(const py::object& V, const py::object& F)
{
  if(py::isinstance<Validated_mesh>(V)) {
    if(!F.is_none()) throw py::type_error("give a lapmesh.Mesh or the arrays (V, F), not both");
    return V.cast<const Validated_mesh&>().mesh;
  }
  if(F.is_none()) throw py::type_error("F is missing: give the arrays (V, F) or a lapmesh.Mesh");
  const Coordinates v = coordinates_of(V);  // V's errors before F's
  return std::make_shared<const Mesh>(mesh_of(v, indices_of(F)).mesh);
}

// Runs `f` with the I/O errors prefixed by the file name (the library leaves it out).
template <typename Function>
decltype(auto) with_path(const std::string& path, Function&& f)
{
  try {
    return f();
  } catch(const lapmesh::Io_error& e) {
    throw lapmesh::Io_error(path + ": " + e.what());
  } catch(const lapmesh::Mesh_error& e) {
    throw lapmesh::Mesh_error(path + ": " + e.what(), e.element(), e.index());
  }
}

// A Python callable called from the computation (any thread): the GIL is taken for the call,
// and an exception it raises propagates and stops the computation. Held through a shared_ptr
// so that the library's copies of the callback never touch Python reference counts.
using Callable = std::shared_ptr<py::object>;
Callable callable(const py::object& f)
{
  if(f.is_none()) return nullptr;
  if(!PyCallable_Check(f.ptr())) throw py::type_error("progress must be callable or None");
  return std::shared_ptr<py::object>(new py::object(f), [](py::object* p) {
    py::gil_scoped_acquire gil;
    delete p;
  });
}

// ---- results -------------------------------------------------------------------------------

struct Curvatures
{
  py::array mean, gaussian, k1, k2, area, normal, laplacian;
};

// A spectral basis, with the mesh it was computed on when there is one (a loaded basis may
// come without it).
class Basis
{
public:
  Basis(std::shared_ptr<const lapmesh::Spectral_basis> basis, std::optional<Mesh> mesh)
    : m_basis(std::move(basis)), m_mesh(std::move(mesh))
  {}
  const lapmesh::Spectral_basis& basis() const { return *m_basis; }
  const std::shared_ptr<const lapmesh::Spectral_basis>& pointer() const { return m_basis; }
  const std::optional<Mesh>& mesh() const { return m_mesh; }

private:
  std::shared_ptr<const lapmesh::Spectral_basis> m_basis;
  std::optional<Mesh> m_mesh;
};

// ---- exceptions ----------------------------------------------------------------------------

const char* exception_classes = R"(
class LapmeshWarning(UserWarning):
    """A result was computed but something about it needs attention (e.g. a time step above
    the explicit stability bound, k splitting an eigenspace, a repaired input)."""


class MeshError(ValueError):
    """The mesh cannot be processed (invalid, degenerate or non-manifold).

    element: 'vertex', 'face', 'edge' or None; index: its index in the input, -1 if none."""

    def __init__(self, message, element=None, index=-1):
        super().__init__(message)
        self.element = element
        self.index = index


class NumericalError(RuntimeError):
    """A factorisation, linear solve or eigen-solve failed."""


class IoError(OSError):
    """A file cannot be read or written, or its content is malformed."""


class ParameterError(ValueError):
    """A setting is out of its range or conflicts with another.

    parameter: the keyword argument at fault; suggested_value: a value of it that resolves
    the problem, or None."""

    def __init__(self, message, parameter=None, suggested_value=None):
        super().__init__(message)
        self.parameter = parameter
        self.suggested_value = suggested_value
)";

void raise(const char* cls, const std::string& message, py::dict kwargs = py::dict())
{
  py::object type = py::module_::import("lapmesh._lapmesh").attr(cls);
  py::object instance = type(message, **kwargs);
  PyErr_SetObject(type.ptr(), instance.ptr());
}

void translate(std::exception_ptr p)
{
  try {
    if(p) std::rethrow_exception(p);
  } catch(const lapmesh::Parameter_error& e) {
    const std::string name = spelling(e.parameter());
    py::dict kw;
    kw["parameter"] = name;
    std::string message = name + ": " + e.what();
    if(!e.suggested_value().empty()) {
      kw["suggested_value"] = e.suggested_value() == "true"    ? py::object(py::bool_(true))
                              : e.suggested_value() == "false" ? py::object(py::bool_(false))
                                                               : py::object(py::str(e.suggested_value()));
      message = std::string(e.what()) + " (set " + name + "=" + value_spelling(e.suggested_value()) + ")";
    }
    raise("ParameterError", message, kw);
  } catch(const lapmesh::Mesh_error& e) {
    using E = lapmesh::Mesh_error::Element;
    py::dict kw;
    kw["element"] = e.element() == E::vertex ? py::str("vertex")
                    : e.element() == E::face ? py::str("face")
                    : e.element() == E::edge ? py::str("edge")
                                             : py::object(py::none());
    kw["index"] = e.index();
    raise("MeshError", e.what(), kw);
  } catch(const lapmesh::Numerical_error& e) {
    raise("NumericalError", e.what());
  } catch(const lapmesh::Io_error& e) {
    raise("IoError", e.what());
  }
}

// The operator of `curvatures` and `laplacian`: the Laplacian and vertex area by name.
double mollification_arg(double factor)
{
  if(!(factor >= 0 && factor <= 1))
    throw lapmesh::Parameter_error("mollification", "must be a number in [0, 1] (got " + std::to_string(factor) + ")",
                                   "1e-05");
  return factor;
}

lapmesh_ops::Curvature_settings operator_settings(const std::string& laplacian, const std::string& area,
                                                  double mollification)
{
  lapmesh_ops::Curvature_settings s;
  s.laplacian = enum_arg<lapmesh::Laplacian>("laplacian", laplacian);
  s.area = enum_arg<lapmesh::Vertex_area>("area", area);
  s.mollification = mollification_arg(mollification);
  return s;
}

} // namespace

PYBIND11_MODULE(_lapmesh, m)
{
  m.doc() = "lapmesh's compiled operations (use the package `lapmesh`, which re-exports them).";
  // Calls on many small meshes would otherwise fault the heap in again at every call.
  lapmesh_ops::keep_heap_between_calls();
  m.def("_set_steady_heap_thresholds", &lapmesh_ops::set_steady_heap_thresholds,
        "glibc's mmap threshold 32 MiB and trim threshold 64 MiB, whatever the environment says; whether glibc "
        "took them (lapmesh.batch.restore_adaptive_malloc)");
  m.def("cached_working_memory", &lapmesh_ops::cached_working_memory,
        "Bytes of freed working arrays (those of 4 MiB or more) that lapmesh keeps for its next call.");
  m.def("release_working_memory", &lapmesh_ops::release_working_memory,
        "Hands the working arrays that lapmesh keeps for its next call back to the system; returns how many bytes "
        "that was.");
  py::exec(exception_classes, m.attr("__dict__"));
  py::register_exception_translator(&translate);

  // The name tables: kind -> [(name, description)], in display order.
  {
    py::dict tables;
    auto add = [&](const char* kind, auto table) {
      py::list entries;
      for(const auto& e : table) entries.append(py::make_tuple(e.name, e.description));
      tables[kind] = entries;
    };
    add("laplacian", lapmesh::name_table<lapmesh::Laplacian>());
    add("area", lapmesh::name_table<lapmesh::Vertex_area>());
    add("scheme", lapmesh::name_table<lapmesh::Smoothing_scheme>());
    add("lambda_unit", lapmesh::name_table<lapmesh::Time_step_unit>());
    add("direction", lapmesh::name_table<lapmesh::Noise_direction>());
    add("scale", lapmesh::name_table<lapmesh::Noise_scale>());
    add("status", lapmesh::name_table<lapmesh::Run_status>());
    m.attr("NAMES") = tables;
  }

  const lapmesh_ops::Curvature_settings curvature_defaults;
  const lapmesh_ops::Spectral_settings spectral_defaults;
  const lapmesh_ops::Smooth_settings smooth_defaults;
  const lapmesh_ops::Noise_settings noise_defaults;

  // ---- meshes ----
  m.def(
    "read_mesh",
    [](const std::string& path) {
      lapmesh_ops::Loaded_mesh loaded;
      {
        py::gil_scoped_release release;
        loaded = with_path(path, [&] { return lapmesh_ops::load_mesh(path); });
      }
      warn({}, loaded.notes);
      return py::make_tuple(rows_array(lapmesh_ops::positions(loaded.mesh)),
                            faces_array(lapmesh_ops::triangles(loaded.mesh)));
    },
    py::arg("path"),
    "Reads a triangle mesh (OFF, OBJ, PLY, STL; polygons are triangulated).\n\n"
    "Returns (V, F): float64 (n, 3) positions and int64 (m, 3) vertex indices, in file order.\n"
    "Raises IoError (unreadable or malformed file) or MeshError (invalid mesh). Repairs the\n"
    "reader made (triangulation, re-orientation) are reported as LapmeshWarning.");

  m.def(
    "write_mesh",
    [](const std::string& path, const py::object& V_arg, const py::object& F_arg) {
      const Coordinates V = coordinates_of(V_arg);
      const Indices F = indices_of(F_arg);
      lapmesh::Vertex_vectors P(V.shape(0), 3);
      std::copy(V.data(), V.data() + V.size(), P.data());
      lapmesh_ops::Triangles tris(std::size_t(F.shape(0)));
      const auto f = F.unchecked<2>();
      for(py::ssize_t i = 0; i < f.shape(0); ++i)
        for(int j = 0; j < 3; ++j) {
          if(f(i, j) < 0 || f(i, j) >= V.shape(0))
            throw lapmesh::Mesh_error("face " + std::to_string(i) + " has the vertex index " + std::to_string(f(i, j)) +
                                        ", outside [0, " + std::to_string(V.shape(0)) + ")",
                                      lapmesh::Mesh_error::Element::face, i);
          tris[std::size_t(i)][std::size_t(j)] = std::size_t(f(i, j));
        }
      py::gil_scoped_release release;
      with_path(path, [&] { lapmesh_ops::write_mesh(path, P, tris); });
    },
    py::arg("path"), py::arg("V"), py::arg("F"),
    "Writes the triangles (V, F) to `path` (format by extension: off, obj, ply, stl), atomically,\n"
    "as the command line writes its results: the geometry is not validated (a reconstruction may\n"
    "have degenerate faces). Coordinates have 17 significant digits (they read back exactly).");

  py::class_<Validated_mesh>(m, "Mesh",
                             "A triangle mesh validated once (finite coordinates, indices in range, no zero-area\n"
                             "face, manifold, consistently oriented): every function takes it in place of (V, F)\n"
                             "and skips converting and validating the arrays again.")
    .def(py::init([](const py::object& V, const py::object& F) { return Validated_mesh{mesh_arg(V, F)}; }),
         py::arg("V"), py::arg("F"))
    .def_static(
      "read",
      [](const std::string& path) {
        lapmesh_ops::Loaded_mesh loaded;
        {
          py::gil_scoped_release release;
          loaded = with_path(path, [&] { return lapmesh_ops::load_mesh(path); });
        }
        warn({}, loaded.notes);
        return Validated_mesh{std::make_shared<const Mesh>(std::move(loaded.mesh))};
      },
      py::arg("path"), "Reads and validates a mesh file (as read_mesh()).")
    .def_property_readonly("V", [](const Validated_mesh& m) { return rows_array(lapmesh_ops::positions(*m.mesh)); },
                           "the vertex positions, float64 (n, 3) (a copy)")
    .def_property_readonly("F", [](const Validated_mesh& m) { return faces_array(lapmesh_ops::triangles(*m.mesh)); },
                           "the triangles, int64 (m, 3), as oriented by the validation (a copy)")
    .def_property_readonly("num_vertices", [](const Validated_mesh& m) { return lapmesh_ops::vertex_count(*m.mesh); })
    .def_property_readonly("num_faces", [](const Validated_mesh& m) { return num_faces(*m.mesh); })
    .def("__repr__", [](const Validated_mesh& m) {
      return "<lapmesh.Mesh: " + std::to_string(lapmesh_ops::vertex_count(*m.mesh)) + " vertices, " +
             std::to_string(num_faces(*m.mesh)) + " faces>";
    });

  // ---- curvature ----
  py::class_<Curvatures>(m, "Curvatures", "Per-vertex curvatures; entry i is vertex i.")
    .def_readonly("mean", &Curvatures::mean, "mean curvature H (positive on a sphere with outward normals)")
    .def_readonly("gaussian", &Curvatures::gaussian, "Gaussian curvature K (angle deficit over the vertex area)")
    .def_readonly("k1", &Curvatures::k1, "larger principal curvature")
    .def_readonly("k2", &Curvatures::k2, "smaller principal curvature")
    .def_readonly("area", &Curvatures::area, "vertex area of the chosen kind")
    .def_readonly("normal", &Curvatures::normal, "unit area-weighted vertex normals, (n, 3)")
    .def_readonly("laplacian", &Curvatures::laplacian, "the Laplacian of the positions, (n, 3)")
    .def("__repr__", [](const Curvatures& c) {
      return "<lapmesh.Curvatures of " + std::to_string(c.mean.shape(0)) + " vertices>";
    });

  m.def(
    "curvatures",
    [](const py::object& V, const py::object& F, const std::string& laplacian, const std::string& area,
       double mollification) {
      const lapmesh_ops::Curvature_settings s = operator_settings(laplacian, area, mollification);
      const std::shared_ptr<const Mesh> held = mesh_arg(V, F);
      const Mesh& mesh = *held;
      lapmesh::Vertex_curvatures c;
      {
        py::gil_scoped_release release;
        c = lapmesh_ops::curvature(mesh, s);
      }
      return Curvatures{vector_array(std::move(c.mean)), vector_array(std::move(c.gaussian)),
                        vector_array(std::move(c.k1)),   vector_array(std::move(c.k2)),
                        vector_array(std::move(c.area)), rows_array(std::move(c.normal)),
                        rows_array(std::move(c.laplacian))};
    },
    py::arg("V"), py::arg("F") = py::none(), py::kw_only(), py::arg("laplacian") = default_name(curvature_defaults.laplacian),
    py::arg("area") = default_name(curvature_defaults.area), py::arg("mollification") = curvature_defaults.mollification,
    "Mean, Gaussian and principal curvatures per vertex (as `lapmesh curvature`).\n\n"
    "laplacian: see lapmesh.names('laplacian'); area: see lapmesh.names('area'); mollification:\n"
    "intrinsic-delaunay only, the triangle-inequality margin in mean edge lengths (0: none).");

  m.def(
    "_laplacian_csr",
    [](const py::object& V, const py::object& F, const std::string& laplacian, const std::string& area,
       double mollification) {
      const lapmesh_ops::Curvature_settings s = operator_settings(laplacian, area, mollification);
      const std::shared_ptr<const Mesh> held = mesh_arg(V, F);
      const Mesh& mesh = *held;
      lapmesh_ops::Csr_laplacian L;
      {
        py::gil_scoped_release release;
        L = lapmesh_ops::laplacian(mesh, s);
      }
      const py::ssize_t n = L.stiffness.rows();
      auto [data, indices, indptr] = csr_arrays(L.stiffness);
      return py::make_tuple(data, indices, indptr, n, vector_array(std::move(L.mass)));
    },
    py::arg("V"), py::arg("F") = py::none(), py::kw_only(), py::arg("laplacian") = default_name(curvature_defaults.laplacian),
    py::arg("area") = default_name(curvature_defaults.area), py::arg("mollification") = curvature_defaults.mollification,
    "(data, indices, indptr, n, mass): the stiffness S in CSR arrays (indices and indptr int32, the\n"
    "assembly's own arrays: not copied) and the diagonal of M.");

  // ---- spectral basis ----
  py::class_<Basis>(m, "SpectralBasis",
                    "The k smallest eigenpairs of -S phi = lambda M phi (as `lapmesh spectrum` and\n"
                    "`lapmesh reconstruct`). It may hold a few more pairs than asked for (a whole last\n"
                    "eigenspace); values and vectors give all it holds.")
    .def(py::init([](const py::object& V, py::object F, std::optional<long long> k_arg, const std::string& laplacian,
                     const std::string& area, double mollification, const py::object& progress) {
           // SpectralBasis(mesh, k): with a lapmesh.Mesh, the second positional argument is k.
           if(py::isinstance<Validated_mesh>(V) && !k_arg && py::isinstance<py::int_>(F)) {
             k_arg = F.cast<long long>();
             F = py::none();
           }
           if(!k_arg) throw py::type_error("k is missing: SpectralBasis(V, F, k) or SpectralBasis(mesh, k)");
           const long long k = *k_arg;
           lapmesh_ops::Spectral_settings s;
           s.k = k;
           if(Callable f = callable(progress))
             s.progress = [f](const lapmesh::Spectral_progress& p) {
               py::gil_scoped_acquire gil;
               (*f)(py::str(p.stage), p.operations, p.attempt, p.elapsed_seconds);
             };
           s.laplacian = enum_arg<lapmesh::Laplacian>("laplacian", laplacian);
           s.area = enum_arg<lapmesh::Vertex_area>("area", area);
           s.mollification = mollification_arg(mollification);
           Mesh mesh = *mesh_arg(V, F);
           std::shared_ptr<const lapmesh::Spectral_basis> b;
           {
             py::gil_scoped_release release;
             b = lapmesh_ops::spectral_basis(mesh, s);
           }
           return Basis(std::move(b), std::move(mesh));
         }),
         py::arg("V"), py::arg("F") = py::none(), py::arg("k") = py::none(), py::kw_only(),
         py::arg("laplacian") = default_name(spectral_defaults.laplacian),
         py::arg("area") = default_name(spectral_defaults.area),
         py::arg("mollification") = spectral_defaults.mollification, py::arg("progress") = py::none(),
         "Computes the k smallest eigenpairs (1 <= k <= number of vertices). progress, when given, is\n"
         "called as progress(stage, solves, attempt, seconds) while the solver runs; an exception it\n"
         "raises stops the computation and propagates.")
    .def_property_readonly("values",
                           [](const Basis& b) {
                             Eigen::VectorXd v = lapmesh_ops::contents(b.basis()).values;
                             return vector_array(std::move(v));
                           },
                           "eigenvalues, ascending")
    .def_property_readonly("vectors",
                           [](const Basis& b) {
                             Eigen::MatrixXd v = lapmesh_ops::contents(b.basis()).vectors;
                             return matrix_array(std::move(v));
                           },
                           "eigenvectors, (n, pairs held), M-orthonormal columns")
    .def_property_readonly("mass",
                           [](const Basis& b) {
                             Eigen::VectorXd v = lapmesh_ops::contents(b.basis()).mass;
                             return vector_array(std::move(v));
                           },
                           "the diagonal of the mass matrix M")
    .def_property_readonly("k", [](const Basis& b) { return lapmesh_ops::contents(b.basis()).requested; },
                           "the k asked for")
    .def_property_readonly("laplacian",
                           [](const Basis& b) { return lapmesh::to_string(lapmesh_ops::contents(b.basis()).laplacian); })
    .def_property_readonly("area",
                           [](const Basis& b) { return lapmesh::to_string(lapmesh_ops::contents(b.basis()).area); })
    .def("__len__", [](const Basis& b) { return lapmesh_ops::contents(b.basis()).values.size(); })
    .def(
      "reconstruct",
      [](const Basis& b, long long k) {
        if(!b.mesh())
          throw py::value_error("this basis was loaded without its mesh: SpectralBasis.load(path, V, F) attaches it");
        lapmesh_ops::Reconstruct_settings s;
        s.k = k;
        lapmesh_ops::Reconstruction r;
        {
          py::gil_scoped_release release;
          r = lapmesh_ops::reconstruct(*b.mesh(), s, b.pointer());
        }
        warn(r.warnings);
        return rows_array(std::move(r.positions));
      },
      py::arg("k"),
      "The mesh's positions rebuilt from the k smallest eigenvectors, x <- sum_{i<k} (x^T M phi_i) phi_i\n"
      "(as `lapmesh reconstruct -k K`). Warns when k splits an eigenspace.")
    .def(
      "project",
      [](const Basis& b, const py::object& signal_arg, long long k) {
        const auto signal = real_array(signal_arg, "signal must be an array of shape (n,) or (n, c)");
        const bool vector = signal.ndim() == 1;
        if(signal.ndim() != 1 && signal.ndim() != 2)
          throw py::value_error("signal must be an array of shape (n,) or (n, c)");
        const py::ssize_t rows = signal.shape(0), cols = vector ? 1 : signal.shape(1);
        Eigen::MatrixXd X(rows, cols);
        for(py::ssize_t i = 0; i < rows; ++i)
          for(py::ssize_t j = 0; j < cols; ++j) X(i, j) = vector ? *signal.data(i) : *signal.data(i, j);
        Eigen::MatrixXd C;
        {
          py::gil_scoped_release release;
          C = lapmesh_ops::project(b.basis(), X, k);
        }
        if(vector) {
          Eigen::VectorXd c = C.col(0);
          return vector_array(std::move(c));
        }
        return matrix_array(std::move(C));
      },
      py::arg("signal"), py::arg("k"),
      "The spectral coefficients Phi_k^T M X of a per-vertex signal X, (n,) -> (k,) or (n, c) -> (k, c).")
    .def(
      "save",
      [](const Basis& b, const std::string& path) {
        py::gil_scoped_release release;
        with_path(path, [&] { lapmesh_ops::save_basis(b.basis(), path); });
      },
      py::arg("path"), "Writes the basis (binary, the file of `lapmesh reconstruct --save-basis`), atomically.")
    .def_static(
      "load",
      [](const std::string& path, const py::object& V, const py::object& F) {
        if(!py::isinstance<Validated_mesh>(V) && V.is_none() != F.is_none())
          throw py::value_error("give both V and F, a lapmesh.Mesh, or nothing");
        std::shared_ptr<const lapmesh::Spectral_basis> b;
        {
          py::gil_scoped_release release;
          b = with_path(path, [&] { return lapmesh_ops::load_basis(path); });
        }
        std::optional<Mesh> mesh;
        if(!V.is_none()) {
          mesh = *mesh_arg(V, F);
          lapmesh_ops::check_basis_fits(*b, *mesh);
        }
        return Basis(std::move(b), std::move(mesh));
      },
      py::arg("path"), py::arg("V") = py::none(), py::arg("F") = py::none(),
      "Reads a basis written by save() or `lapmesh reconstruct --save-basis`. With (V, F), the basis\n"
      "is checked against that mesh and reconstruct() works on it.")
    .def("__repr__", [](const Basis& b) {
      const auto c = lapmesh_ops::contents(b.basis());
      return "<lapmesh.SpectralBasis: " + std::to_string(c.values.size()) + " pairs of " +
             std::to_string(c.mass.size()) + " vertices, " + lapmesh::to_string(c.laplacian) + ", " +
             lapmesh::to_string(c.area) + " area>";
    });

  // ---- smoothing ----
  m.def(
    "smooth",
    [](const py::object& V, const py::object& F, const std::string& scheme, const py::object& lam,
       const std::string& lambda_unit, long long iterations, const std::string& laplacian, const std::string& area,
       double mollification, bool fixed_operator, bool restore_volume, bool restore_area, bool fix_boundary, bool reuse_factorization,
       const py::object& progress) {
      lapmesh_ops::Smooth_settings s;
      if(Callable f = callable(progress))
        s.progress = [f](int done, int total) {
          py::gil_scoped_acquire gil;
          (*f)(done, total);
        };
      s.scheme = enum_arg<lapmesh::Smoothing_scheme>("scheme", scheme);
      const auto unit = enum_arg<lapmesh::Time_step_unit>("lambda_unit", lambda_unit);
      // A number goes through the text parser as its shortest round-trip repr: the same checks.
      const std::string lam_text = py::isinstance<py::str>(lam) ? lam.cast<std::string>()
                                   : (py::isinstance<py::float_>(lam) || py::isinstance<py::int_>(lam))
                                     ? py::repr(py::float_(lam)).cast<std::string>()
                                     : throw lapmesh::Parameter_error("lambda", "expected a positive number or 'auto'");
      s.lambda = lapmesh_ops::parse_time_step(lam_text, unit);
      s.iterations = iterations;
      s.laplacian = enum_arg<lapmesh::Laplacian>("laplacian", laplacian);
      s.area = enum_arg<lapmesh::Vertex_area>("area", area);
      s.mollification = mollification_arg(mollification);
      s.fixed_operator = fixed_operator;
      s.restore_volume = restore_volume;
      s.restore_area = restore_area;
      s.fix_boundary = fix_boundary;
      s.reuse_factorization = reuse_factorization;
      lapmesh_ops::check(s);
      Mesh mesh = *mesh_arg(V, F);
      lapmesh_ops::Smooth_result r;
      {
        py::gil_scoped_release release;
        r = lapmesh_ops::smooth(mesh, s);
      }
      warn(r.warnings);
      py::dict report;
      report["lambda"] = r.lambda;
      report["stability_bound"] = r.stability_bound;
      report["stability_bound_exact"] = r.report.stability_bound_exact;
      report["above_stability_bound"] = r.report.above_stability_bound;
      report["iterations"] = r.report.iterations;
      report["free_vertices"] = r.report.free_vertices;
      report["solver"] = r.report.solver;
      report["factorizations"] = r.report.factorizations;
      py::list collapsed;
      for(const auto& c : r.report.collapsed_components)
        collapsed.append(py::dict(py::arg("iteration") = c.iteration, py::arg("first_vertex") = c.first_vertex,
                                  py::arg("vertices") = c.vertices, py::arg("area_over_lambda") = c.area_over_lambda));
      report["collapsed_components"] = collapsed;
      report["seconds"] = py::dict(py::arg("assembly") = r.report.assembly_seconds,
                                   py::arg("analysis") = r.report.analysis_seconds,
                                   py::arg("factorization") = r.report.factorization_seconds,
                                   py::arg("solve") = r.report.solve_seconds);
      report["warnings"] = warning_texts(r.warnings);
      return py::make_tuple(rows_array(lapmesh_ops::positions(mesh)), report);
    },
    py::arg("V"), py::arg("F") = py::none(), py::kw_only(), py::arg("scheme") = default_name(smooth_defaults.scheme),
    py::arg("lam") = "auto", py::arg("lambda_unit") = default_name(smooth_defaults.lambda.unit),
    py::arg("iterations") = smooth_defaults.iterations, py::arg("laplacian") = default_name(smooth_defaults.laplacian),
    py::arg("area") = default_name(smooth_defaults.area), py::arg("mollification") = smooth_defaults.mollification,
    py::arg("fixed_operator") = smooth_defaults.fixed_operator,
    py::arg("restore_volume") = smooth_defaults.restore_volume,
    py::arg("restore_area") = smooth_defaults.restore_area, py::arg("fix_boundary") = smooth_defaults.fix_boundary,
    py::arg("reuse_factorization") = smooth_defaults.reuse_factorization, py::arg("progress") = py::none(),
    "Laplacian smoothing (as `lapmesh smooth`). Returns (V2, report).\n\n"
    "scheme: see lapmesh.names('scheme'); lam: a positive time step in lambda_unit, or 'auto'\n"
    "(0.9 x the stability bound for explicit, one mean edge length squared otherwise);\n"
    "fix_boundary=False is the command line's --free-boundary. The report holds lambda (absolute),\n"
    "stability_bound (explicit; NaN otherwise), iterations, solver, timings and the warnings\n"
    "(also issued as LapmeshWarning). progress, when given, is called as progress(done, total)\n"
    "after each iteration; an exception it raises stops the smoothing and propagates.");

  // ---- denoising study ----
  const lapmesh::Denoising_study_settings study_defaults;
  auto names_of = [](const auto& values) {
    std::vector<std::string> out;
    for(auto v : values) out.push_back(lapmesh::to_string(v));
    return out;
  };
  m.def(
    "denoise_study",
    [](const py::object& V, const py::object& F, const std::vector<double>& levels,
       const std::vector<std::string>& schemes, const std::vector<std::string>& laplacians,
       const std::vector<double>& lambdas, const std::string& lambda_unit, int iterations, std::uint64_t seed,
       const std::string& direction, const std::string& area, double mollification, bool restore_volume,
       bool fixed_operator, double hausdorff_spacing) {
      lapmesh::Denoising_study_settings s;
      auto numbers = [](const char* name, const std::vector<double>& values, bool allow_zero) {
        if(values.empty()) throw lapmesh::Parameter_error(name, "the list is empty");
        for(double v : values)
          if(!std::isfinite(v) || v < 0 || (!allow_zero && v == 0))
            throw lapmesh::Parameter_error(name, std::string("every value must be a ") +
                                                   (allow_zero ? "finite number >= 0" : "positive finite number") +
                                                   " (got " + py::repr(py::float_(v)).cast<std::string>() + ")");
        return values;
      };
      auto kinds = [](const char* name, const std::vector<std::string>& values, auto tag) {
        using Enum = decltype(tag);
        if(values.empty()) throw lapmesh::Parameter_error(name, "the list is empty");
        std::vector<Enum> out;
        for(const auto& v : values) out.push_back(enum_arg<Enum>(name, v));
        return out;
      };
      s.noise_levels = numbers("levels", levels, true);
      s.time_steps = numbers("lambdas", lambdas, false);
      s.schemes = kinds("schemes", schemes, lapmesh::Smoothing_scheme{});
      s.laplacians = kinds("laplacians", laplacians, lapmesh::Laplacian{});
      s.unit = enum_arg<lapmesh::Time_step_unit>("lambda_unit", lambda_unit);
      s.iterations = iterations;
      s.seed = seed;
      s.noise_direction = enum_arg<lapmesh::Noise_direction>("direction", direction);
      s.area = enum_arg<lapmesh::Vertex_area>("area", area);
      s.mollification = mollification_arg(mollification);
      s.restore_volume = restore_volume;
      s.fixed_operator = fixed_operator;
      s.hausdorff_spacing = hausdorff_spacing;
      lapmesh_ops::check(s);
      const std::shared_ptr<const Mesh> held = mesh_arg(V, F);
      const Mesh& mesh = *held;
      lapmesh::Denoising_study study;
      {
        py::gil_scoped_release release;
        study = lapmesh_ops::denoise_study(mesh, s);
      }
      const std::size_t n = study.records.size();
      auto column = [&](auto field) {
        Eigen::VectorXd v(Eigen::Index(n), 1);
        for(std::size_t i = 0; i < n; ++i) v[Eigen::Index(i)] = field(study.records[i]);
        return vector_array(std::move(v));
      };
      py::array_t<std::int64_t> iteration{py::ssize_t(n)};
      py::list scheme, laplacian, status, error;
      for(std::size_t i = 0; i < n; ++i) {
        const auto& r = study.records[i];
        iteration.mutable_at(py::ssize_t(i)) = r.iteration;
        scheme.append(lapmesh::to_string(r.scheme));
        laplacian.append(lapmesh::to_string(r.laplacian));
        status.append(lapmesh::to_string(r.status));
        error.append(r.message);
      }
      using R = lapmesh::Denoising_record;
      py::dict out;
      out["noise_level"] = column([](const R& r) { return r.noise_level; });
      out["sigma"] = column([](const R& r) { return r.sigma; });
      out["scheme"] = scheme;
      out["laplacian"] = laplacian;
      out["time_step"] = column([](const R& r) { return r.time_step; });
      out["lambda"] = column([](const R& r) { return r.lambda; });
      out["stability_bound"] = column([](const R& r) { return r.stability_bound; });
      out["iteration"] = iteration;
      out["rms_distance"] = column([](const R& r) { return r.deviation.rms_distance; });
      out["hausdorff_distance"] = column([](const R& r) { return r.deviation.hausdorff_distance; });
      out["hausdorff_coarsening"] = column([](const R& r) { return r.deviation.hausdorff_coarsening; });
      out["normal_angle_error"] = column([](const R& r) { return r.deviation.normal_angle_error; });
      out["volume_change"] = column([](const R& r) { return r.deviation.volume_change; });
      out["status"] = status;
      out["error"] = error;
      return out;
    },
    py::arg("V"), py::arg("F") = py::none(), py::kw_only(), py::arg("levels") = study_defaults.noise_levels,
    py::arg("schemes") = names_of(study_defaults.schemes), py::arg("laplacians") = names_of(study_defaults.laplacians),
    py::arg("lambdas") = study_defaults.time_steps, py::arg("lambda_unit") = default_name(study_defaults.unit),
    py::arg("iterations") = study_defaults.iterations, py::arg("seed") = study_defaults.seed,
    py::arg("direction") = default_name(study_defaults.noise_direction),
    py::arg("area") = default_name(study_defaults.area), py::arg("mollification") = study_defaults.mollification,
    py::arg("restore_volume") = study_defaults.restore_volume,
    py::arg("fixed_operator") = study_defaults.fixed_operator,
    py::arg("hausdorff_spacing") = study_defaults.hausdorff_spacing,
    "The denoising study (as `lapmesh denoise-study`): noise at each level, then every scheme,\n"
    "Laplacian and time step (lambdas, in lambda_unit) for `iterations` steps, measured against\n"
    "the clean mesh after each step. Returns the records as columns (a dict of equal-length numpy\n"
    "arrays and lists, e.g. for pandas.DataFrame): noise_level, sigma, scheme, laplacian,\n"
    "time_step, lambda, stability_bound, iteration, rms_distance, hausdorff_distance (relative to\n"
    "the bounding-box diagonal), hausdorff_coarsening (how many times coarser than hausdorff_spacing\n"
    "its sampling grid was, where it would have held more than 16 samples per corner; 1: as asked),\n"
    "normal_angle_error (degrees), volume_change, status, error.");

  // ---- noise ----
  m.def(
    "add_noise",
    [](const py::object& V, const py::object& F, double level, std::uint64_t seed, const std::string& direction,
       const std::string& scale) {
      lapmesh_ops::Noise_settings s;
      s.level = level;
      s.seed = seed;
      s.direction = enum_arg<lapmesh::Noise_direction>("direction", direction);
      s.scale = enum_arg<lapmesh::Noise_scale>("scale", scale);
      lapmesh_ops::check(s);
      Mesh mesh = *mesh_arg(V, F);
      {
        py::gil_scoped_release release;
        lapmesh_ops::add_noise(mesh, s);
      }
      return rows_array(lapmesh_ops::positions(mesh));
    },
    py::arg("V"), py::arg("F") = py::none(), py::kw_only(), py::arg("level") = noise_defaults.level,
    py::arg("seed") = noise_defaults.seed, py::arg("direction") = default_name(noise_defaults.direction),
    py::arg("scale") = default_name(noise_defaults.scale),
    "Seeded Gaussian vertex noise (as `lapmesh noise`): sigma = level x the scale's length.\n"
    "The same seed gives the same output on every platform.");
}
