// The thin binding: numpy arrays in (viewed, not copied, when float64 and C-contiguous),
// the GIL released while the engine runs, numpy arrays out (the engine's vectors, not copied).

#include <m3c2/m3c2.hpp>

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/function.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <atomic>
#include <memory>
#include <optional>

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using Points = nb::ndarray<const double, nb::shape<-1, 3>, nb::c_contig, nb::device::cpu>;

m3c2::PointsView view(const Points& a) { return {a.data(), a.shape(0)}; }

template <class T>
nb::ndarray<nb::numpy, T> to_numpy(std::vector<T>&& values, std::size_t columns = 1) {
  auto* owned = new std::vector<T>(std::move(values));
  nb::capsule owner(owned, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
  const std::size_t rows = owned->size() / columns;
  if (columns == 1) return nb::ndarray<nb::numpy, T>(owned->data(), {rows}, owner);
  return nb::ndarray<nb::numpy, T>(owned->data(), {rows, columns}, owner);
}

nb::ndarray<nb::numpy, std::uint8_t> status_array(const std::vector<m3c2::PointStatus>& s) {
  std::vector<std::uint8_t> codes(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) codes[i] = static_cast<std::uint8_t>(s[i]);
  return to_numpy(std::move(codes));
}

/// Bridges a Python progress callable to the engine. Python errors raised inside it, and
/// Ctrl-C noticed by it, are kept and re-raised once the engine has stopped and the GIL is back.
class ProgressBridge {
 public:
  explicit ProgressBridge(nb::object callback) : callback_(std::move(callback)) {}
  ~ProgressBridge() {
    nb::gil_scoped_acquire gil;
    error_.reset();
  }

  m3c2::RunOptions options(int threads) {
    m3c2::RunOptions run;
    run.threads = threads;
    run.progress = [this](std::size_t done, std::size_t total) {
      nb::gil_scoped_acquire gil;
      if (PyErr_CheckSignals() != 0) return keep_error();
      if (callback_.is_none()) return true;
      try {
        const nb::object answer = callback_(done, total);
        return answer.is_none() || nb::cast<bool>(answer);
      } catch (nb::python_error& e) {
        e.restore();
        return keep_error();
      }
    };
    return run;
  }

  /// After the engine threw Cancelled: re-raise what stopped it (GIL held).
  [[noreturn]] void raise() {
    if (error_) {
      error_->restore();
      error_.reset();
      throw nb::python_error();
    }
    throw m3c2::Cancelled();
  }

 private:
  bool keep_error() {
    error_.emplace();  // takes the pending Python error
    return false;
  }
  nb::object callback_;
  std::optional<nb::python_error> error_;
};

template <class Fn>
auto run_engine(nb::object progress, int threads, Fn&& fn) {
  ProgressBridge bridge(std::move(progress));
  const m3c2::RunOptions run = bridge.options(threads);
  try {
    nb::gil_scoped_release nogil;
    return fn(run);
  } catch (const m3c2::Cancelled&) {
    bridge.raise();
  }
}

nb::dict result_dict(m3c2::Result&& r) {
  nb::dict d;
  d["status"] = status_array(r.status);
  d["distance"] = to_numpy(std::move(r.distance));
  d["lod"] = to_numpy(std::move(r.lod));
  d["significant"] = to_numpy(std::move(r.significant));
  d["n1"] = to_numpy(std::move(r.n1));
  d["n2"] = to_numpy(std::move(r.n2));
  d["sigma1"] = to_numpy(std::move(r.sigma1));
  d["sigma2"] = to_numpy(std::move(r.sigma2));
  d["i1"] = to_numpy(std::move(r.i1));
  d["i2"] = to_numpy(std::move(r.i2));
  d["normal"] = to_numpy(std::move(r.normal), 3);
  d["normal_scale"] = to_numpy(std::move(r.normal_scale));
  d["roughness"] = to_numpy(std::move(r.roughness));
  return d;
}

}  // namespace

NB_MODULE(_core, m) {
  m.doc() = "m3c2 engine (C++): see python/m3c2kit/__init__.py for the documented API";

  nb::enum_<m3c2::NormalSource>(m, "NormalSource")
      .value("reference", m3c2::NormalSource::kReference)
      .value("compared", m3c2::NormalSource::kCompared)
      .value("mean", m3c2::NormalSource::kMean)
      .value("vertical", m3c2::NormalSource::kVertical)
      .value("horizontal", m3c2::NormalSource::kHorizontal)
      .value("core", m3c2::NormalSource::kCorePoints);
  nb::enum_<m3c2::Statistic>(m, "Statistic")
      .value("mean", m3c2::Statistic::kMean)
      .value("median", m3c2::Statistic::kMedian);
  nb::enum_<m3c2::Variance>(m, "Variance")
      .value("sample", m3c2::Variance::kSample)
      .value("population", m3c2::Variance::kPopulation);
  nb::enum_<m3c2::DepthSearch>(m, "DepthSearch")
      .value("single", m3c2::DepthSearch::kSinglePass)
      .value("two_pass", m3c2::DepthSearch::kTwoPass)
      .value("progressive", m3c2::DepthSearch::kProgressive);
  nb::enum_<m3c2::ScaleSelection>(m, "ScaleSelection")
      .value("most_planar", m3c2::ScaleSelection::kMostPlanar)
      .value("cloudcompare", m3c2::ScaleSelection::kCloudCompare);

  nb::class_<m3c2::Params>(m, "Params")
      .def(nb::init<>())
      .def_rw("normal_diameters", &m3c2::Params::normal_diameters)
      .def_rw("normal_source", &m3c2::Params::normal_source)
      .def_rw("scale_selection", &m3c2::Params::scale_selection)
      .def_rw("min_points_normal", &m3c2::Params::min_points_normal)
      .def_rw("min_points_multiscale", &m3c2::Params::min_points_multiscale)
      .def_rw("normal_subsample_spacing", &m3c2::Params::normal_subsample_spacing)
      .def_prop_rw(
          "orientation_direction",
          [](const m3c2::Params& p) {
            const auto& d = p.orientation.direction;
            return std::vector<double>{d[0], d[1], d[2]};
          },
          [](m3c2::Params& p, const std::vector<double>& d) {
            if (d.size() != 3) throw m3c2::InvalidArgument("orientation_direction needs 3 values");
            for (int a = 0; a < 3; ++a) p.orientation.direction[a] = d[a];
          })
      .def_prop_rw(
          "orientation_points", [](const m3c2::Params& p) { return p.orientation.points; },
          [](m3c2::Params& p, const std::vector<double>& pts) { p.orientation.points = pts; })
      .def_rw("projection_diameter", &m3c2::Params::projection_diameter)
      .def_rw("max_depth", &m3c2::Params::max_depth)
      .def_rw("depth_search", &m3c2::Params::depth_search)
      .def_rw("first_pass_depth", &m3c2::Params::first_pass_depth)
      .def_rw("positive_search_only", &m3c2::Params::positive_search_only)
      .def_rw("statistic", &m3c2::Params::statistic)
      .def_rw("variance", &m3c2::Params::variance)
      .def_rw("registration_error", &m3c2::Params::registration_error)
      .def_rw("confidence", &m3c2::Params::confidence)
      .def_rw("min_points", &m3c2::Params::min_points)
      .def_rw("t_statistic", &m3c2::Params::t_statistic)
      .def_rw("bootstrap_samples", &m3c2::Params::bootstrap_samples)
      .def_rw("bootstrap_seed", &m3c2::Params::bootstrap_seed);

  nb::exception<m3c2::Cancelled>(m, "Cancelled", PyExc_RuntimeError);

  m.def("status_names", [] {
    std::vector<std::string> names;
    for (int s = 0; s <= static_cast<int>(m3c2::PointStatus::kTooFewPointsForLod); ++s)
      names.emplace_back(m3c2::status_name(static_cast<m3c2::PointStatus>(s)));
    return names;
  });

  m.attr("MAX_BOOTSTRAP_SAMPLES") = m3c2::kMaxBootstrapSamples;  // params.hpp: resamples per core point

  m.def("max_abs_coordinate", &m3c2::max_abs_coordinate, "params"_a,
        "The largest |coordinate| of a cloud compute() indexes with these parameters.");

  m.def(
      "compute",
      [](const Points& reference, const Points& compared, const Points& core, const m3c2::Params& params,
         std::optional<Points> core_normals, int threads, nb::object progress) {
        std::vector<double> normals;
        if (core_normals) normals.assign(core_normals->data(), core_normals->data() + 3 * core_normals->shape(0));
        return result_dict(run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::compute(view(reference), view(compared), view(core), params, run, normals);
        }));
      },
      "reference"_a, "compared"_a, "core_points"_a, "params"_a, "core_normals"_a = nb::none(), "threads"_a = 0,
      "progress"_a = nb::none());

  m.def(
      "compute_normals",
      [](const Points& cloud, const Points& core, const m3c2::Params& params, int threads, nb::object progress) {
        m3c2::NormalsResult r = run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::compute_normals(view(cloud), view(core), params, run);
        });
        nb::dict d;
        d["status"] = status_array(r.status);
        d["normal"] = to_numpy(std::move(r.normal), 3);
        d["normal_scale"] = to_numpy(std::move(r.normal_scale));
        d["roughness"] = to_numpy(std::move(r.roughness));
        d["count"] = to_numpy(std::move(r.count));
        return d;
      },
      "cloud"_a, "core_points"_a, "params"_a, "threads"_a = 0, "progress"_a = nb::none());

  m.def(
      "roughness_by_scale",
      [](const Points& cloud, const Points& core, const std::vector<double>& diameters, m3c2::Variance variance,
         std::uint32_t min_points, int threads, nb::object progress) {
        const std::size_t scales = diameters.size();
        auto values = run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::roughness_by_scale(view(cloud), view(core), diameters, variance, min_points, run);
        });
        return to_numpy(std::move(values), scales);
      },
      "cloud"_a, "core_points"_a, "diameters"_a, "variance"_a = m3c2::Variance::kSample, "min_points"_a = 3,
      "threads"_a = 0, "progress"_a = nb::none());

  m.def(
      "subsample_min_spacing",
      [](const Points& points, double spacing) {
        std::vector<std::uint64_t> kept;
        {
          nb::gil_scoped_release nogil;
          kept = m3c2::subsample_min_spacing(view(points), spacing);
        }
        return to_numpy(std::move(kept));
      },
      "points"_a, "min_spacing"_a);

  m.def(
      "grid_core_points",
      [](const Points& points, double cell) {
        m3c2::Grid g;
        {
          nb::gil_scoped_release nogil;
          g = m3c2::grid_core_points(view(points), cell);
        }
        nb::dict d;
        d["x0"] = g.x0, d["y0"] = g.y0, d["cell"] = g.cell, d["rows"] = g.rows, d["cols"] = g.cols;
        d["core_points"] = to_numpy(std::move(g.core_points), 3);
        d["row"] = to_numpy(std::move(g.row));
        d["col"] = to_numpy(std::move(g.col));
        return d;
      },
      "points"_a, "cell"_a);

  // C2C baselines of section 3.4 (include/m3c2/baselines.hpp, docs/analysis.md).
  m.def(
      "c2c",
      [](const Points& reference, const Points& compared, const std::string& model, double model_radius,
         std::uint32_t model_neighbours, const std::string& rule, int threads, nb::object progress) {
        m3c2::C2CParams p;
        if (model == "none") p.model = m3c2::LocalModel::kNone;
        else if (model == "plane") p.model = m3c2::LocalModel::kPlane;
        else throw m3c2::InvalidArgument("model must be 'none' or 'plane', got '" + model + "'");
        if (rule == "closer") p.rule = m3c2::ModelRule::kCloser;
        else if (rule == "model") p.rule = m3c2::ModelRule::kModelOnly;
        else throw m3c2::InvalidArgument("rule must be 'closer' or 'model', got '" + rule + "'");
        p.model_radius = model_radius;
        p.model_neighbours = model_neighbours;
        m3c2::C2CResult r = run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::c2c(view(reference), view(compared), p, run);
        });
        nb::dict d;
        d["distance"] = to_numpy(std::move(r.distance));
        d["nearest"] = to_numpy(std::move(r.nearest));
        d["model_distance"] = to_numpy(std::move(r.model_distance));
        d["hf_distance"] = to_numpy(std::move(r.hf_distance));
        d["model_count"] = to_numpy(std::move(r.model_count));
        return d;
      },
      "reference"_a, "compared"_a, "model"_a = "none", "model_radius"_a = 0.0, "model_neighbours"_a = 6,
      "rule"_a = "closer", "threads"_a = 0, "progress"_a = nb::none());
}
