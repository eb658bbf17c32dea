// The Python module ffloc._ffloc (docs/python.md): the library's datasets, maps, localization, PnP
// solver and evaluation, called exactly as the CLI calls them.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include <nlohmann/json.hpp>

#include "ffloc/core/error.h"
#include "ffloc/core/progress.h"
#include "ffloc/core/threads.h"
#include "ffloc/data/dataset.h"
#include "ffloc/eval/method_evaluation.h"
#include "ffloc/eval/report.h"
#include "ffloc/io/image.h"
#include "ffloc/localization/localization_json.h"
#include "ffloc/model/model_options.h"
#include "ffloc/model/torch_threads.h"
#include "ffloc/pipeline/map_building.h"
#include "ffloc/pipeline/map_localizer.h"
#include "ffloc/pose/reprojection.h"

namespace py = pybind11;

namespace ffloc::python {
namespace {

std::function<LoadedModel()> modelLoader(const std::string& model, const std::string& dtype) {
  return [=] {
    ModelLoadOptions options;
    options.dtype = parseNetworkDtype(dtype);
    return loadModel(model, options);
  };
}

// The library's JSON as Python objects, through Python's own parser so numbers keep every digit.
py::object toPython(const nlohmann::json& value) { return py::module_::import("json").attr("loads")(jsonText(value)); }

std::string shapeText(const py::array& array) {
  std::string text = "(";
  for (py::ssize_t d = 0; d < array.ndim(); ++d) text += (d ? ", " : "") + std::to_string(array.shape(d));
  return text + (array.ndim() == 1 ? ",)" : ")");
}

std::string dtypeText(const py::array& array) { return py::str(array.dtype()).cast<std::string>(); }

// A float64 view of `value` (converted when it is another numeric type), with `field` named when
// it is not numbers at all.
py::array_t<double, py::array::c_style | py::array::forcecast> floatArray(const py::handle& value, const std::string& field) {
  // ensure() gives a null array instead of raising. A list is made an array once, in its own
  // type, and that array converted.
  const py::array natural = py::array::ensure(value);
  if (!natural) throw InputError(field + ": expected numbers");
  // Booleans, strings and objects were cast too: intrinsics (True, True, True, True) were ones.
  const char kind = natural.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u')
    throw InputError(field + ": expected numbers, got an array of " + py::str(natural.dtype()).cast<std::string>());
  auto array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(natural);
  if (!array) throw InputError(field + ": expected numbers");
  return array;
}

py::array_t<double> toArray(const Eigen::Matrix4d& matrix) {
  py::array_t<double> array({4, 4});
  auto out = array.mutable_unchecked<2>();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out(r, c) = matrix(r, c);
  return array;
}

py::array_t<double> toArray(const Eigen::Matrix3d& matrix) {
  py::array_t<double> array({3, 3});
  auto out = array.mutable_unchecked<2>();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out(r, c) = matrix(r, c);
  return array;
}

// Intrinsics from a 3x3 matrix or (fx, fy, cx, cy), with optional OpenCV distortion.
Intrinsics intrinsicsFrom(const py::handle& value, const py::handle& distortion) {
  if (value.is_none()) throw InputError("intrinsics: required (a 3x3 matrix or fx, fy, cx, cy)");
  const auto array = floatArray(value, "intrinsics");
  Intrinsics k;
  if (array.ndim() == 2 && array.shape(0) == 3 && array.shape(1) == 3) {
    const auto K = array.unchecked<2>();
    if (K(0, 1) != 0 || K(1, 0) != 0 || K(2, 0) != 0 || K(2, 1) != 0 || K(2, 2) != 1)
      throw InputError("intrinsics: a 3x3 matrix must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]");
    k.fx = K(0, 0);
    k.fy = K(1, 1);
    k.cx = K(0, 2);
    k.cy = K(1, 2);
  } else if (array.ndim() == 1 && array.shape(0) == 4) {
    const auto v = array.unchecked<1>();
    k.fx = v(0);
    k.fy = v(1);
    k.cx = v(2);
    k.cy = v(3);
  } else {
    throw InputError("intrinsics: expected a 3x3 matrix or (fx, fy, cx, cy), got shape " + shapeText(array));
  }
  if (!distortion.is_none()) {
    const auto coefficients = floatArray(distortion, "distortion");
    const py::ssize_t n = coefficients.ndim() == 1 ? coefficients.shape(0) : -1;
    if (n != 4 && n != 5 && n != 8)
      throw InputError("distortion: expected 4, 5 or 8 OpenCV coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6]]), got shape " +
                       shapeText(coefficients));
    k.distortion.assign(coefficients.data(), coefficients.data() + n);
  }
  return k;
}

// Points as an N x `columns` float64 array, copied into the solver's layout.
template <typename Vector>
std::vector<Vector> pointsFrom(const py::handle& value, const std::string& field) {
  constexpr int columns = Vector::RowsAtCompileTime;
  const auto array = floatArray(value, field);
  if (array.ndim() != 2 || array.shape(1) != columns)
    throw InputError(field + ": expected an N x " + std::to_string(columns) + " array, got shape " + shapeText(array));
  std::vector<Vector> points(static_cast<size_t>(array.shape(0)));
  const auto v = array.unchecked<2>();
  for (size_t i = 0; i < points.size(); ++i) {
    for (int c = 0; c < columns; ++c) points[i][c] = v(static_cast<py::ssize_t>(i), c);
    // Such a pair was left out without a word (199 of 200 used).
    if (!points[i].allFinite()) throw InputError(field + ": row " + std::to_string(i) + " holds a value that is not finite");
  }
  return points;
}

// Ctrl-C during a long call with the interpreter's lock released was heard only when the call
// returned (a build_map ran on and replaced its map): Python's handler runs at each progress
// step, and the KeyboardInterrupt it raises stops the work there (StopCheck).
StopCheck stopOnInterrupt() {
  return StopCheck([] {
    py::gil_scoped_acquire locked;
    return PyErr_CheckSignals() != 0;
  });
}

// The thread pools at `threads` (none: as they are) for a call, with Ctrl-C heard while it waits
// for calls at another count to end (ThreadCountLease).
std::unique_ptr<ThreadCountLease> leasePools(std::optional<int> threads) {
  const StopCheck interruptible = stopOnInterrupt();
  return std::make_unique<ThreadCountLease>(threads);
}

// A path or file name from the library as os.fsdecode gives it: bytes that are not UTF-8 kept as
// surrogates, so that Python opens the same file with it.
py::str pythonPath(const std::string& path) {
  PyObject* decoded = PyUnicode_DecodeFSDefaultAndSize(path.data(), static_cast<py::ssize_t>(path.size()));
  if (decoded == nullptr) throw py::error_already_set();
  return py::reinterpret_steal<py::str>(decoded);
}

// Text from the library for people to read (a repr, an error message): bytes that are not UTF-8
// (a file's name) shown as escapes, \xe9, where a cast to str raised UnicodeDecodeError.
py::str readableText(const std::string& text) {
  PyObject* decoded = PyUnicode_DecodeUTF8(text.data(), static_cast<py::ssize_t>(text.size()), "backslashreplace");
  if (decoded == nullptr) throw py::error_already_set();
  return py::reinterpret_steal<py::str>(decoded);
}

// A str, bytes or os.PathLike argument; InputError naming `argument` for anything else (None gave
// Python's own TypeError, naming no argument).
std::string pathArgument(const py::handle& value, const std::string& argument, const std::string& expected) {
  if (!py::isinstance<py::str>(value) && !py::isinstance<py::bytes>(value) && !py::hasattr(value, "__fspath__"))
    throw InputError(argument + ": expected " + expected + ", got " + py::str(py::type::of(value).attr("__name__")).cast<std::string>());
  // fsencode: str, bytes and os.PathLike of either, to the bytes the file system has, UTF-8 or not
  // (a name of other bytes, decoded by Python with surrogates, was refused as a cast error).
  const std::string path = py::bytes(py::module_::import("os").attr("fsencode")(value)).cast<std::string>();
  // build_map(out='') built the whole map, then failed to rename it into place.
  if (path.empty()) throw InputError(argument + ": the path is empty");
  return path;
}

// An image as a path (read as `ffloc localize` reads it) or an H x W x 3 uint8 RGB array, which
// the returned Mat shares without copying while `keep` holds it.
cv::Mat imageFrom(const py::handle& image, py::object& keep, std::string& name) {
  if (py::isinstance<py::bytes>(image)) {
    // A file's encoded bytes (open(...).read()) were taken as a path: a 77,000-character error.
    const std::string bytes = image.cast<std::string>();
    if (bytes.size() > PATH_MAX || bytes.find('\0') != std::string::npos)
      throw InputError("image: got " + std::to_string(bytes.size()) +
                       " bytes that are no path (an encoded image?): pass its path, or the image decoded to an H x W "
                       "x 3 uint8 array");
  }
  if (py::isinstance<py::str>(image) || py::isinstance<py::bytes>(image) || py::hasattr(image, "__fspath__")) {
    // The GIL is released only once the path is a C++ string.
    const std::string path = pathArgument(image, "image", "a path or an H x W x 3 uint8 array");
    if (name.empty()) name = path;
    py::gil_scoped_release unlocked;
    const auto pools = leasePools(std::nullopt);
    return readImageRgb(path);
  }
  if (!py::isinstance<py::array>(image)) throw InputError("image: expected a path or an H x W x 3 uint8 array");
  py::array array = py::reinterpret_borrow<py::array>(image);
  // Equal, not the same object: uint8 with metadata, or marked big-endian, is still uint8.
  if (!array.dtype().equal(py::dtype::of<uint8_t>()))
    throw InputError("image: dtype must be uint8, got " + dtypeText(array));
  if (array.ndim() != 3 || array.shape(2) != 3)
    throw InputError("image: shape must be H x W x 3 (RGB), got " + shapeText(array));
  if (array.shape(0) == 0 || array.shape(1) == 0) throw InputError("image: is empty, shape " + shapeText(array));
  // As a file is refused by its decoder: a 40000 x 40000 array ran a minute, copied 4.8 GB and
  // heard no Ctrl-C (an outside probe).
  constexpr py::ssize_t kMaxImagePixels = py::ssize_t{1} << 30;  // OpenCV's OPENCV_IO_MAX_IMAGE_PIXELS
  if (array.shape(0) > kMaxImagePixels / array.shape(1))
    throw InputError("image: shape " + shapeText(array) + " is more than the " + std::to_string(kMaxImagePixels) +
                     " pixels an image file may decode to; resize it");
  // Rows may be strided (a crop of a larger array); pixels within a row must be packed.
  if (array.strides(2) != 1 || array.strides(1) != 3 || array.strides(0) < 3 * array.shape(1))
    array = py::module_::import("numpy").attr("ascontiguousarray")(array);
  keep = array;
  if (name.empty()) name = "query";
  return cv::Mat(static_cast<int>(array.shape(0)), static_cast<int>(array.shape(1)), CV_8UC3,
                 const_cast<void*>(array.data()), static_cast<size_t>(array.strides(0)));
}

// A Mat handed to NumPy without copying: the array owns the Mat's reference.
py::array imageArray(cv::Mat rgb) {
  auto* owner = new cv::Mat(std::move(rgb));
  py::capsule free_when_done(owner, [](void* mat) { delete static_cast<cv::Mat*>(mat); });
  return py::array_t<uint8_t>({owner->rows, owner->cols, 3},
                              {static_cast<py::ssize_t>(owner->step[0]), py::ssize_t{3}, py::ssize_t{1}}, owner->data,
                              free_when_done);
}

// An (n, N) array of n Eigen vectors of N doubles, handed to NumPy without copying.
template <int N>
py::array vectorArray(std::vector<Eigen::Matrix<double, N, 1>> vectors) {
  using Vectors = std::vector<Eigen::Matrix<double, N, 1>>;
  static_assert(sizeof(Eigen::Matrix<double, N, 1>) == N * sizeof(double), "vectors must be packed for a zero-copy view");
  auto* owner = new Vectors(std::move(vectors));
  py::capsule free_when_done(owner, [](void* held) { delete static_cast<Vectors*>(held); });
  return py::array_t<double>({static_cast<py::ssize_t>(owner->size()), py::ssize_t{N}},
                             owner->empty() ? nullptr : owner->front().data(), free_when_done);
}

// Which of `pairs` lie within `threshold_px` of the pose (positive depth), as PnP counts its
// inliers; every one false without a pose.
py::array_t<bool> inlierMask(const Correspondences& pairs, const Intrinsics& camera,
                             const std::optional<Pose>& camera_to_world, double threshold_px) {
  py::array_t<bool> mask(static_cast<py::ssize_t>(pairs.size()));
  std::fill(mask.mutable_data(), mask.mutable_data() + pairs.size(), false);
  if (!camera_to_world) return mask;
  for (const int index : findInliers(pairs.pixels, pairs.points, camera, camera_to_world->inverse(), threshold_px))
    mask.mutable_data()[index] = true;
  return mask;
}

// A keyword or dict option's value as T, or InputError naming the field: pybind11's own cast
// said only "Unable to cast Python instance to C++ type", and silently took 1.5 for an integer.
// NumPy integers and floats are taken as the Python numbers they stand for.
template <typename T>
T optionValue(const py::handle& value, const std::string& field) {
  const auto refuse = [&](const std::string& expected) -> T {
    throw InputError(field + ": expected " + expected + ", got " + py::repr(value).cast<std::string>());
  };
  const bool boolean = py::isinstance<py::bool_>(value);
  if constexpr (std::is_same_v<T, bool>) {
    return boolean ? value.cast<bool>() : refuse("True or False");
  } else if constexpr (std::is_integral_v<T>) {
    if (boolean || !PyIndex_Check(value.ptr())) return refuse("an integer");
    try {
      return value.cast<T>();
    } catch (const py::cast_error&) {
      return refuse(std::is_signed_v<T> ? "an integer within range" : "a non-negative integer within range");
    }
  } else if constexpr (std::is_floating_point_v<T>) {
    if (boolean || py::isinstance<py::str>(value) || !PyNumber_Check(value.ptr())) return refuse("a number");
    try {
      return value.cast<T>();
    } catch (const py::cast_error&) {  // numbers that are no real number: complex, arrays
      return refuse("a number");
    }
  } else {
    return py::isinstance<py::str>(value) ? value.cast<std::string>() : refuse("a string");
  }
}

// A thread count as the CLI's --threads takes it: any other type was pybind11's TypeError, not
// ffloc.Error, and named no argument (an outside probe).
int threadsValue(const py::handle& value) {
  const int64_t threads = optionValue<int64_t>(value, "threads");
  if (const std::string problem = threadCountProblem(threads); !problem.empty()) throw InputError("threads: " + problem);
  return static_cast<int>(threads);
}

// A seed in the CLI's and the server's range: Python took 2^63 to 2^64 - 1, which they refuse
// (an outside probe), so a seed written down in one could not be given to the other.
uint64_t seedValue(const py::handle& value, const std::string& field) {
  const uint64_t seed = optionValue<uint64_t>(value, field);
  if (seed > static_cast<uint64_t>(std::numeric_limits<int64_t>::max()))
    throw InputError(field + ": expected an integer in [0, " + std::to_string(std::numeric_limits<int64_t>::max()) +
                     "], got " + std::to_string(seed));
  return seed;
}

// `methods`: one name, or a list or tuple of them (pybind11's list cast refused a plain string
// with a TypeError that named no argument).
std::vector<std::string> methodNames(const py::handle& value) {
  if (py::isinstance<py::str>(value)) return {value.cast<std::string>()};
  if (!py::isinstance<py::list>(value) && !py::isinstance<py::tuple>(value))
    throw InputError("methods: expected a method name or a list of them, got " + py::repr(value).cast<std::string>());
  std::vector<std::string> names;
  for (const py::handle& name : value) names.push_back(optionValue<std::string>(name, "methods"));
  return names;
}

// Query options from keyword arguments, named as the CLI's flags.
QuerySettings querySettings(const py::kwargs& kwargs, std::vector<std::string>& unused) {
  QuerySettings settings;
  for (const auto& [key, value] : kwargs) {
    const std::string name = py::str(key).cast<std::string>();
    if (name == "preset") settings.preset = optionValue<std::string>(value, name);
    else if (name == "top_k") settings.top_k = optionValue<int64_t>(value, name);
    else if (name == "features") settings.features = optionValue<int64_t>(value, name);
    else if (name == "seed") settings.seed = seedValue(value, name);
    else if (name == "selection") settings.selection = optionValue<std::string>(value, name);
    else if (name == "retrieval") settings.retrieval = optionValue<std::string>(value, name);
    else if (name == "solver") settings.solver = optionValue<std::string>(value, name);
    else if (name == "verify") settings.verify = optionValue<bool>(value, name);
    else if (name == "pose_guided") settings.pose_guided = optionValue<bool>(value, name);
    else unused.push_back(name);
  }
  return settings;
}

void refuseUnknown(const std::vector<std::string>& unused, const std::string& function) {
  if (!unused.empty())
    throw InputError(unused.front() + ": not an option of " + function +
                     " (query options: preset, top_k, features, seed, selection, retrieval, solver, verify, pose_guided)");
}

// pybind11 (2.10) lets `Map.__new__(Map)` make an instance whose C++ object is never built; the
// first method called on it reads unbuilt memory (an outside probe: a segmentation fault from
// len() of a Map, from Scene.mapping_indices() and Frame.distortion). Such a `__new__` refuses,
// naming what makes one: always for the classes the library makes (Map, Result, Scene, Frame),
// and without arguments for those Python constructs (Localizer: its __init__ takes the map, and
// the library's own instances never pass through __new__).
enum class MadeBy { kLibrary, kConstructor };
template <typename Class>
void refuseEmptyNew(py::class_<Class>& bound, MadeBy made_by, const std::string& how) {
  const std::string message = "ffloc." + std::string(py::str(bound.attr("__name__"))) + " cannot be made empty: " + how;
  const newfunc make_instance = reinterpret_cast<PyTypeObject*>(bound.ptr())->tp_new;
  bound.def_static("__new__", [=](const py::handle& type, const py::args& args, const py::kwargs& kwargs) -> py::object {
    if (made_by == MadeBy::kLibrary || (args.empty() && kwargs.empty())) throw py::type_error(message);
    return py::reinterpret_steal<py::object>(make_instance(reinterpret_cast<PyTypeObject*>(type.ptr()), args.ptr(), kwargs.ptr()));
  });
}

Scene sceneFrom(const py::handle& value, const std::string& format) {
  if (py::isinstance<Scene>(value)) return value.cast<Scene>();
  const std::string path = pathArgument(value, "dataset", "a folder path or an ffloc.Scene");
  py::gil_scoped_release unlocked;
  const auto pools = leasePools(std::nullopt);
  return loadDataset(path, format);
}

// A map file opened for queries, with the model it needs.
struct Map {
  std::shared_ptr<const MapLocalizer> opened;
  std::string path;
  int threads = 0;
  std::optional<MapBuildReport> build_report;

  static Map load(const std::string& path, const std::string& model, const std::string& dtype, int threads) {
    py::gil_scoped_release unlocked;
    const auto pools = leasePools(threads);
    Map map;
    map.opened = std::make_shared<MapLocalizer>(openMapLocalizer(path, modelLoader(model, dtype)));
    map.path = path;
    map.threads = threads;
    return map;
  }
  const Localizer& localizer() const { return *opened->localizer; }
};

struct Result {
  nlohmann::json answer;  // what `ffloc localize --json` prints
  std::optional<Pose> camera_to_world;
  Correspondences pairs;  // in `camera`'s grid: the undistorted full-size query
  Intrinsics camera;
  double inlier_threshold_px = 0;
};

// The mapping images a query used, named as Python names files (pythonPath).
py::list selectedNames(const Result& r) {
  py::list names;
  if (!r.answer.contains("selected")) return names;
  for (const nlohmann::json& name : r.answer["selected"]) names.append(pythonPath(name.get<std::string>()));
  return names;
}

// The answer's JSON with its file names as pythonPath gives them: through JSON text, a name that
// is not UTF-8 lost its bytes to U+FFFD and no longer named the file.
py::object answerDict(const Result& r) {
  py::object answer = toPython(r.answer);
  answer["name"] = pythonPath(r.answer["name"].get<std::string>());
  if (r.answer.contains("selected")) answer["selected"] = selectedNames(r);
  return answer;
}

// As the CLI refuses their flags: a setting the map's method ignores was taken silently.
void refuseSettingsTheMapIgnores(const Map& map, const std::vector<std::string>& given) {
  const LocalizationMethod method = map.localizer().method();
  for (const std::string& field : given)
    if (!methodUsesSetting(method, field))
      throw InputError(field + ": the map is a " + std::string(toString(method)) + " map, which does not use it");
}

// Map::load with the model and dtype given, if any, refused with the settings named in `given`
// when the map's method ignores them.
Map loadMapRefusingIgnoredSettings(const std::string& path, const std::optional<std::string>& model,
                                   const std::optional<std::string>& dtype, int threads,
                                   std::vector<std::string> given = {}) {
  Map map = Map::load(path, model.value_or("default"), dtype.value_or("f32"), threads);
  if (model) given.push_back("model");
  if (dtype) given.push_back("dtype");
  refuseSettingsTheMapIgnores(map, given);
  return map;
}

class PyLocalizer {
 public:
  PyLocalizer(Map map, LocalizeOptions options) : map_(std::move(map)), options_(std::move(options)) {}

  // `name` as any object: a wrong type was pybind11's TypeError, not ffloc.Error, and its message
  // printed the whole image array (an outside probe). None is no name.
  Result localize(const py::handle& image, const py::handle& intrinsics, const py::handle& distortion,
                  const py::handle& name_given) const {
    std::string name = name_given.is_none() ? "" : optionValue<std::string>(name_given, "name");
    py::object keep;
    const Intrinsics camera = intrinsicsFrom(intrinsics, distortion);
    const cv::Mat rgb = imageFrom(image, keep, name);
    py::gil_scoped_release unlocked;
    const auto pools = leasePools(map_.threads);
    LocalizationResult result = map_.localizer().localize(rgb, camera, name, options_);
    Result out;
    out.answer = localizationJson(name, result, map_.localizer());
    if (result.pnp.ok()) out.camera_to_world = result.pnp.camera_to_world;
    out.pairs = std::move(result.correspondences);
    out.camera = result.camera;
    out.inlier_threshold_px = options_.pnp.inlier_threshold_px;
    return out;
  }
  const Map& map() const { return map_; }

 private:
  Map map_;
  LocalizeOptions options_;
};

PnpOptions pnpOptions(const py::dict& given) {
  PnpOptions options;
  for (const auto& [key, value] : given) {
    const std::string name = py::str(key).cast<std::string>();
    if (name == "solver") options.solver = parsePnpSolver(optionValue<std::string>(value, name));
    else if (name == "inlier_threshold_px") options.inlier_threshold_px = optionValue<double>(value, name);
    else if (name == "max_iterations") options.max_iterations = optionValue<int>(value, name);
    else if (name == "success_probability") options.success_probability = optionValue<double>(value, name);
    else if (name == "min_inliers") options.min_inliers = optionValue<int>(value, name);
    else if (name == "max_correspondences") options.max_correspondences = optionValue<size_t>(value, name);
    else if (name == "refine") options.refine = optionValue<bool>(value, name);
    else if (name == "seed") options.seed = seedValue(value, name);
    else
      throw InputError("options: unknown key '" + name +
                       "' (known: solver, inlier_threshold_px, max_iterations, success_probability, min_inliers, "
                       "max_correspondences, refine, seed)");
  }
  LocalizeOptions checked;  // the solver's fields are checked where the localizer's are
  checked.pnp = options;
  checked.check();
  return options;
}

py::tuple estimateAbsolutePose(const py::handle& points2d, const py::handle& points3d, const py::handle& intrinsics,
                               const py::object& options, const std::optional<std::pair<int, int>>& image_size,
                               const py::handle& threads_given) {
  const int threads = threadsValue(threads_given);
  Correspondences pairs;
  pairs.pixels = pointsFrom<Eigen::Vector2d>(points2d, "points2d");
  pairs.points = pointsFrom<Eigen::Vector3d>(points3d, "points3d");
  if (pairs.pixels.size() != pairs.points.size())
    throw InputError("points3d: " + std::to_string(pairs.points.size()) + " points for " +
                     std::to_string(pairs.pixels.size()) + " pixels in points2d");
  // No confidences: every pair passes the confidence filter.
  pairs.confidences.assign(pairs.size(), std::numeric_limits<float>::infinity());
  Intrinsics camera = intrinsicsFrom(intrinsics, py::none());
  // The solver's test against chance needs the image's area; without it, the principal point is
  // taken to be the image's centre.
  // Beyond int, the side was cast to -2147483648 (undefined behaviour) and named image_size; a
  // principal point at (0, 0), as for pixels measured from the image's centre, made a 1 x 1 image.
  const auto sideAround = [](double centre, const char* name) {
    constexpr double kSmallestSide = 16;
    const double side = std::ceil(2 * centre + 1);
    if (!(side >= kSmallestSide && side <= std::numeric_limits<int>::max())) {
      std::ostringstream what;
      what << "intrinsics: " << name << " = " << centre << " puts the image centre where no image is (pass image_size)";
      throw InputError(what.str());
    }
    return static_cast<int>(side);
  };
  camera.width = image_size ? image_size->first : sideAround(camera.cx, "cx");
  camera.height = image_size ? image_size->second : sideAround(camera.cy, "cy");
  if (camera.width <= 0 || camera.height <= 0)
    throw InputError("image_size: must be positive, got " + std::to_string(camera.width) + "x" +
                     std::to_string(camera.height));
  // As Localizer.localize refuses them: a principal point outside the image gave a pose metres
  // off reported as success. Without image_size the image is made to fit the principal point, and
  // the focal length is still judged against it (1e300 px went on to RANSAC).
  try {
    checkIntrinsicsFitImage(camera, camera.width, camera.height);
  } catch (const InputError& e) {
    if (image_size) throw;
    throw InputError(std::string(e.what()) + " (the size twice the principal point; pass image_size)");
  }
  if (!options.is_none() && !py::isinstance<py::dict>(options))
    throw InputError("options: expected a dict of PnP options, got " +
                     py::str(py::type::of(options).attr("__name__")).cast<std::string>());
  const PnpOptions pnp = pnpOptions(options.is_none() ? py::dict() : options.cast<py::dict>());
  PnpResult result;
  {
    py::gil_scoped_release unlocked;
    const auto pools = leasePools(threads);
    result = estimatePose(pairs, camera, pnp);
  }
  const py::array_t<bool> mask =
      inlierMask(pairs, camera, result.ok() ? std::optional<Pose>(result.camera_to_world) : std::nullopt, pnp.inlier_threshold_px);
  py::dict info;
  info["status"] = toString(result.status);
  info["success"] = result.ok();
  info["inliers"] = result.inliers;
  info["used_correspondences"] = result.used_correspondences;
  info["seconds"] = result.seconds;
  py::object pose = result.status == PnpStatus::kSuccess ? py::object(toArray(result.camera_to_world.matrix())) : py::none();
  return py::make_tuple(pose, mask, info);
}

py::dict reportDict(const MapBuildReport& report) {
  py::dict out;
  out["images"] = report.images;
  out["previous_images"] = report.previous_images;
  out["added"] = report.added;
  out["every_frame"] = report.every_frame;
  out["skipped_duplicates"] = report.skipped_duplicates;
  out["skipped_featureless"] = report.featureless.size();
  out["featureless_images"] = report.featureless;
  out["points"] = report.points;
  out["points_from_depth"] = report.points_from_depth;
  out["links"] = report.links;
  out["seconds"] = report.seconds;
  return out;
}

}  // namespace
}  // namespace ffloc::python

PYBIND11_MODULE(_ffloc, m) {
  using namespace ffloc;
  using namespace ffloc::python;
  m.doc() = "ffloc: visual relocalization (docs/python.md)";
  // The library's InputError: a ValueError whose message names the file or field at fault, and
  // the library option it points to as the remedy by its name here.
  static py::exception<InputError> error(m, "Error", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr raised) {
    try {
      if (raised) std::rethrow_exception(raised);
    } catch (const InputError& e) {
      std::string message = e.what();
      const std::string option = "MappingOptions::vlad";
      if (const size_t at = message.find(option); at != std::string::npos)
        message.replace(at, option.size(), "build_map(vlad=True)");
      // PyErr_SetString raised a UnicodeDecodeError in place of a message naming such a file.
      PyErr_SetObject(error.ptr(), readableText(message).ptr());
    } catch (const Stopped& e) {
      // Python's handler already raised the KeyboardInterrupt that stopped the work.
      if (!PyErr_Occurred()) PyErr_SetString(PyExc_KeyboardInterrupt, e.what());
    }
  });

  py::class_<Frame> frame_class(m, "Frame", "One posed image of a dataset");
  refuseEmptyNew(frame_class, MadeBy::kLibrary, "Scene.frames holds a dataset's frames");
  frame_class
      .def_property_readonly("name", [](const Frame& f) { return pythonPath(f.name); })
      .def_property_readonly("image_path", [](const Frame& f) { return pythonPath(f.image_path.string()); })
      .def_property_readonly("intrinsics", [](const Frame& f) { return toArray(f.intrinsics.K()); }, "3x3 K")
      .def_property_readonly("width", [](const Frame& f) { return f.intrinsics.width; })
      .def_property_readonly("height", [](const Frame& f) { return f.intrinsics.height; })
      .def_property_readonly("distortion", [](const Frame& f) { return f.intrinsics.distortion; })
      .def_property_readonly("camera_to_world", [](const Frame& f) { return toArray(f.camera_to_world.matrix()); },
                             "4x4, OpenCV axes (x right, y down, z forward), scene units")
      .def_property_readonly("depth_path",
                             [](const Frame& f) -> py::object {
                               return f.depth ? py::object(pythonPath(f.depth->path.string())) : py::none();
                             })
      .def_property_readonly("split", [](const Frame& f) { return std::string(toString(f.split)); })
      .def("__repr__", [](const Frame& f) { return readableText("<ffloc.Frame " + f.name + " (" + toString(f.split) + ")>"); });

  py::class_<Scene> scene_class(m, "Scene", "A dataset: posed frames with their split");
  refuseEmptyNew(scene_class, MadeBy::kLibrary, "ffloc.load_dataset(path) reads one");
  scene_class
      .def_property_readonly("name", [](const Scene& s) { return pythonPath(s.name); })
      .def_property_readonly("root", [](const Scene& s) { return pythonPath(s.root.string()); })
      .def_readonly("format", &Scene::format)
      .def_readonly("metric", &Scene::metric)
      .def_property_readonly("frames",
                             [](py::object self) {
                               py::list frames;
                               for (const Frame& frame : self.cast<const Scene&>().frames)
                                 frames.append(py::cast(frame, py::return_value_policy::reference_internal, self));
                               return frames;
                             })
      .def("mapping_indices", &Scene::mappingIndices)
      .def("query_indices", &Scene::queryIndices)
      .def("__len__", [](const Scene& s) { return s.frames.size(); })
      .def("__repr__", [](const Scene& s) {
        return readableText("<ffloc.Scene " + s.name + " (" + s.format + ", " + std::to_string(s.frames.size()) + " frames)>");
      });

  m.def("load_dataset", [](const py::handle& path, const std::string& format) { return sceneFrom(path, format); },
        py::arg("path"), py::arg("format") = "auto", "Reads a dataset folder (format 'auto' detects it)");

  m.def("read_image",
        [](const py::handle& path_argument) {
          const std::string path = pathArgument(path_argument, "path", "an image file path");
          cv::Mat rgb;
          {
            py::gil_scoped_release unlocked;
            const auto pools = leasePools(std::nullopt);
            rgb = readImageRgb(path);
          }
          return imageArray(std::move(rgb));
        },
        py::arg("path"), "An image file as ffloc reads it: H x W x 3 uint8 RGB");

  py::class_<Map> map_class(m, "Map", "A map file opened for queries");
  refuseEmptyNew(map_class, MadeBy::kLibrary, "ffloc.Map.load(path) opens one; ffloc.build_map and Localizer.map return one");
  map_class
      .def_static("load",
                  [](const py::handle& path, const std::optional<std::string>& model,
                     const std::optional<std::string>& dtype, const py::handle& threads) {
                    return loadMapRefusingIgnoredSettings(pathArgument(path, "path", "a map file path"), model,
                                                          dtype, threadsValue(threads));
                  },
                  py::arg("path"), py::arg("model") = py::none(), py::arg("dtype") = py::none(),
                  py::arg("threads") = 0, "Opens a map from 'ffloc map' (model: for fastforward maps)")
      .def_property_readonly("path", [](const Map& map) { return pythonPath(map.path); })
      .def_property_readonly("method", [](const Map& map) { return std::string(toString(map.localizer().method())); })
      .def_property_readonly("description", [](const Map& map) { return map.opened->description; })
      .def_property_readonly("metric", [](const Map& map) { return map.localizer().metric(); })
      .def_property_readonly("names",
                             [](const Map& map) {
                               py::list names;
                               for (const MapCamera& camera : map.localizer().cameras()) names.append(pythonPath(camera.name));
                               return names;
                             })
      .def_property_readonly("camera_to_world",
                             [](const Map& map) {
                               const auto& cameras = map.localizer().cameras();
                               py::array_t<double> poses({static_cast<py::ssize_t>(cameras.size()), py::ssize_t{4}, py::ssize_t{4}});
                               auto out = poses.mutable_unchecked<3>();
                               for (size_t i = 0; i < cameras.size(); ++i) {
                                 const Eigen::Matrix4d T = cameras[i].camera_to_world.matrix();
                                 for (int r = 0; r < 4; ++r)
                                   for (int c = 0; c < 4; ++c) out(static_cast<py::ssize_t>(i), r, c) = T(r, c);
                               }
                               return poses;
                             },
                             "N x 4 x 4: the mapping cameras")
      // py::object, not size_t: pybind11 refused -1 with a TypeError and its signatures, not ffloc.Error.
      .def("points",
           [](const Map& map, const py::object& max_points) {
             return vectorArray<3>(map.localizer().mapPoints(optionValue<size_t>(max_points, "max_points")));
           },
           py::arg("max_points") = 100000, "At most max_points world points (N x 3); none for maps without points")
      .def_property_readonly("build_report",
                             [](const Map& map) -> py::object {
                               return map.build_report ? py::object(reportDict(*map.build_report)) : py::none();
                             })
      .def("__len__", [](const Map& map) { return map.localizer().cameras().size(); })
      .def("__repr__", [](const Map& map) { return readableText("<ffloc.Map " + map.path + ": " + map.opened->description + ">"); });

  m.def(
      "build_map",
      [](const py::handle& scene_or_path, const py::handle& out_argument, const std::string& method, const py::object& model,
         const py::object& dtype, bool append, const py::object& use_depth, const py::object& max_image_size,
         const py::object& max_features, const py::object& vlad, const py::handle& threads_given,
         const std::string& format, bool quiet) {
        const int threads = threadsValue(threads_given);
        const std::string out = pathArgument(out_argument, "out", "a map file path");
        MapBuildOptions options;
        options.method = parseLocalizationMethod(method);
        options.append = append;
        // Keywords left at None take the defaults; one passed that the build would ignore is
        // refused, as 'ffloc map' refuses the flag.
        SetMapBuildOptions given;
        const auto take = [&](const py::object& value, const char* name, auto& field) {
          if (value.is_none()) return;
          field = optionValue<std::decay_t<decltype(field)>>(value, name);
          given.push_back(name);
        };
        std::string model_spec = "default", precision = "f32";
        take(model, "model", model_spec);
        take(dtype, "dtype", precision);
        take(use_depth, "use_depth", options.classical.use_depth);
        take(max_image_size, "max_image_size", options.classical.sift.max_image_size);
        take(max_features, "max_features", options.classical.sift.max_features);
        take(vlad, "vlad", options.fastforward.vlad);
        if (const std::string problem = ignoredOptionProblem(options, given); !problem.empty()) throw InputError(problem);
        options.classical.quiet = quiet;
        options.fastforward.quiet = quiet;
        const Scene scene = sceneFrom(scene_or_path, format);
        MapBuildReport report;
        {
          py::gil_scoped_release unlocked;
          const StopCheck interruptible = stopOnInterrupt();
          const auto pools = leasePools(threads);
          report = buildMap(scene, out, options, modelLoader(model_spec, precision));
        }
        Map map = Map::load(out, model_spec, precision, threads);
        map.build_report = report;
        return map;
      },
      py::arg("scene_or_path"), py::arg("out"), py::arg("method") = "classical", py::arg("model") = py::none(),
      py::arg("dtype") = py::none(), py::arg("append") = false, py::arg("use_depth") = py::none(),
      py::arg("max_image_size") = py::none(), py::arg("max_features") = py::none(), py::arg("vlad") = py::none(),
      py::arg("threads") = 0, py::arg("format") = "auto", py::arg("quiet") = true,
      "Maps the scene's mapping split (every frame of a scene without a split) into the file `out` "
      "(as 'ffloc map') and opens it");

  py::class_<Result> result_class(m, "Result", "One query's answer");
  refuseEmptyNew(result_class, MadeBy::kLibrary, "Localizer.localize returns one");
  result_class
      .def_property_readonly("pose",
                             [](const Result& r) -> py::object {
                               return r.camera_to_world ? py::object(toArray(r.camera_to_world->matrix())) : py::none();
                             },
                             "camera_to_world 4x4 (None when PnP found no pose)")
      .def_property_readonly("quaternion",
                             [](const Result& r) -> py::object {
                               if (!r.camera_to_world) return py::none();
                               return py::array_t<double>(4, r.answer["world_to_camera"]["qwxyz"].get<std::vector<double>>().data());
                             },
                             "world_to_camera rotation (w, x, y, z), as COLMAP and hloc write it")
      .def_property_readonly("translation",
                             [](const Result& r) -> py::object {
                               if (!r.camera_to_world) return py::none();
                               return py::array_t<double>(3, r.answer["world_to_camera"]["t"].get<std::vector<double>>().data());
                             },
                             "world_to_camera translation")
      .def_property_readonly("status", [](const Result& r) { return r.answer["status"].get<std::string>(); })
      .def_property_readonly("localized", [](const Result& r) { return r.answer["status"] == "localized"; })
      .def_property_readonly("reason", [](const Result& r) { return r.answer.value("reason", std::string()); })
      .def_property_readonly("inliers", [](const Result& r) { return r.answer["inliers"].get<int>(); })
      .def_property_readonly("selected", [](const Result& r) { return selectedNames(r); })
      .def_property_readonly("timings", [](const Result& r) { return toPython(r.answer["timings_ms"]); }, "milliseconds per stage")
      // Reachable only through to_dict() before (an outside review).
      .def_property_readonly(
          "evidence",
          [](const Result& r) -> py::object {
            const auto found = r.answer.find("evidence");
            return found == r.answer.end() || found->is_null() ? py::none() : toPython(*found);
          },
          "what the verdict judged (docs/verdict.md): inlier ratio and spread, the second estimate's agreement, the "
          "predicted uncertainty, the intrinsics fits; None without a pose")
      // An outside review could count the inliers but not see them.
      .def_property_readonly(
          "correspondences",
          [](const Result& r) {
            py::dict pairs;
            pairs["pixels"] = vectorArray<2>(r.pairs.pixels);
            pairs["points"] = vectorArray<3>(r.pairs.points);
            pairs["confidences"] = py::array_t<float>(static_cast<py::ssize_t>(r.pairs.size()), r.pairs.confidences.data());
            pairs["inliers"] = inlierMask(r.pairs, r.camera, r.camera_to_world, r.inlier_threshold_px);
            pairs["camera"] = toArray(r.camera.K());
            return pairs;
          },
          "the pairs PnP chose from: 'pixels' (n, 2) in the undistorted query's grid, whose 3x3 K is 'camera', "
          "'points' (n, 3) in the world frame, 'confidences' (n,), and 'inliers' (n,), those within PnP's inlier "
          "threshold of the pose (none without one); PnP counts its inliers among the at most max_correspondences "
          "pairs it drew, so 'inliers' may hold more than Result.inliers")
      .def("to_dict", [](const Result& r) { return answerDict(r); }, "What 'ffloc localize --json' prints")
      .def("__repr__", [](const Result& r) {
        return "<ffloc.Result " + r.answer["status"].get<std::string>() + ", " +
               std::to_string(r.answer["inliers"].get<int>()) + " inliers>";
      });

  py::class_<PyLocalizer> localizer_class(m, "Localizer", "Localizes queries against a map with its method");
  refuseEmptyNew(localizer_class, MadeBy::kConstructor, "ffloc.Localizer(map) makes one");
  localizer_class
      .def(py::init([](const py::handle& map, const std::optional<std::string>& model,
                       const std::optional<std::string>& dtype, const py::handle& threads_given,
                       const py::kwargs& kwargs) {
             const int threads = threadsValue(threads_given);
             std::vector<std::string> unused;
             const LocalizeOptions options = localizeOptions(querySettings(kwargs, unused));
             refuseUnknown(unused, "Localizer");
             std::vector<std::string> given;
             for (const auto& [key, value] : kwargs) given.push_back(py::str(key).cast<std::string>());
             Map opened;
             if (py::isinstance<Map>(map)) {
               // A Map holds the model it was opened with: another one named here was ignored.
               if (model || dtype)
                 throw InputError(std::string(model ? "model" : "dtype") +
                                  ": a Map is opened with its model; pass it to ffloc.Map.load(path, model=..., "
                                  "dtype=...), or give Localizer the map's path");
               opened = map.cast<Map>();
               resolveThreadCount(threads);  // refused here rather than at the first query
               opened.threads = threads;
               refuseSettingsTheMapIgnores(opened, given);
             } else {
               opened = loadMapRefusingIgnoredSettings(pathArgument(map, "map", "an ffloc.Map or a map file path"),
                                                       model, dtype, threads, given);
             }
             return PyLocalizer(std::move(opened), options);
           }),
           py::arg("map"), py::arg("model") = py::none(), py::arg("dtype") = py::none(), py::arg("threads") = 0,
           "map: a Map or a map file; keyword query options as the CLI's flags (preset, top_k, features, seed, "
           "selection, retrieval, solver, verify, pose_guided)")
      .def("localize", &PyLocalizer::localize, py::arg("image"), py::arg("intrinsics"),
           py::arg("distortion") = py::none(), py::arg("name") = py::none(),
           "image: a path or an H x W x 3 uint8 RGB array; intrinsics: 3x3 or (fx, fy, cx, cy)")
      .def_property_readonly("map", &PyLocalizer::map);

  m.def("estimate_absolute_pose", &estimateAbsolutePose, py::arg("points2d"), py::arg("points3d"),
        py::arg("intrinsics"), py::arg("options") = py::none(), py::arg("image_size") = py::none(),
        py::arg("threads") = 0,
        "PnP-RANSAC on N 2D-3D pairs (pixels undistorted, OpenCV convention): (camera_to_world 4x4 or None, "
        "inlier mask, info dict). image_size (width, height) defaults to twice the principal point.");

  m.def(
      "evaluate",
      [](const py::handle& dataset, const py::handle& method_names, const py::object& max_queries,
         const py::object& use_depth, const py::object& model, const py::object& dtype, const py::handle& threads_given,
         const std::string& format, bool quiet, const py::kwargs& kwargs) {
        const int threads = threadsValue(threads_given);
        std::vector<std::string> unused;
        const LocalizeOptions localize = localizeOptions(querySettings(kwargs, unused));
        refuseUnknown(unused, "evaluate");
        const std::vector<std::string> methods = methodNames(method_names);
        if (const std::string problem = methodListProblem(methods); !problem.empty())
          throw InputError("methods: " + problem);
        for (const auto& [key, value] : kwargs) {
          const std::string setting = py::str(key).cast<std::string>();
          if (const std::string problem = settingNoMethodUsesProblem(methods, setting); !problem.empty())
            throw InputError(setting + ": " + problem);
        }
        // Given for a method not evaluated, they changed nothing without a word, where the CLI
        // refuses --no-depth, --model and --dtype (an outside probe).
        for (const auto& [setting, value] : {std::pair{"model", &model}, {"dtype", &dtype}})
          if (!value->is_none())
            if (const std::string problem = settingNoMethodUsesProblem(methods, setting); !problem.empty())
              throw InputError(std::string(setting) + ": " + problem);
        if (!use_depth.is_none() && std::find(methods.begin(), methods.end(), "classical") == methods.end())
          throw InputError("use_depth: only classical uses it, and methods does not run it");
        const size_t query_count = optionValue<size_t>(max_queries, "max_queries");  // before the dataset is read
        const Scene scene = sceneFrom(dataset, format);
        MethodEvaluationOptions options;
        options.localize = localize;
        options.evaluation.pnp = localize.pnp;
        options.evaluation.verdict = localize.verdict;
        options.evaluation.max_queries = query_count;
        options.evaluation.quiet = quiet;
        options.use_depth = use_depth.is_none() || optionValue<bool>(use_depth, "use_depth");
        const std::string model_name = model.is_none() ? "default" : optionValue<std::string>(model, "model");
        const std::string dtype_name = dtype.is_none() ? "f32" : optionValue<std::string>(dtype, "dtype");
        // Loaded on first use and shared by the methods that need it.
        auto loaded = std::make_shared<std::optional<LoadedModel>>();
        options.fastforward = [=](const Scene& scene) {
          if (!*loaded) *loaded = modelLoader(model_name, dtype_name)();
          MappingOptions mapping;
          mapping.quiet = quiet;
          mapping.vlad = localize.retrieval == FastForwardRetrieval::kVlad;
          return inMemoryFastForwardLocalizer(**loaded, scene, mapping);
        };
        std::vector<MethodSummary> summaries;
        {
          py::gil_scoped_release unlocked;
          const StopCheck interruptible = stopOnInterrupt();
          const auto pools = leasePools(threads);
          for (const std::string& method : methods) summaries.push_back(summarize(evaluateMethod(scene, method, options)));
        }
        return toPython(summaryJson(summaries, scene.metric ? std::vector<std::string>{} : std::vector{scene.name}));
      },
      py::arg("dataset"), py::arg("methods") = "classical", py::arg("max_queries") = 0,
      py::arg("use_depth") = py::none(), py::arg("model") = py::none(), py::arg("dtype") = py::none(),
      py::arg("threads") = 0, py::arg("format") = "auto", py::arg("quiet") = true,
      "Localizes the dataset's queries with each method; the summary as 'ffloc eval --json' writes it");
}
