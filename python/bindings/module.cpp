// The thin binding: numpy arrays in (viewed, not copied, when float64 and C-contiguous),
// the GIL released while the engine runs, numpy arrays out (the engine's vectors, not copied).

#include <m3c2/m3c2.hpp>

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/function.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <optional>

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using Points = nb::ndarray<const double, nb::shape<-1, 3>, nb::c_contig, nb::device::cpu>;

m3c2::PointsView view(const Points& a) { return {a.data(), a.shape(0)}; }

using Ids = nb::ndarray<const std::uint32_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using Table = nb::ndarray<const double, nb::shape<-1, 8>, nb::c_contig, nb::device::cpu>;
using Flat = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;

/// One cloud's per-point uncertainty inputs: precisions (N, 3), scan-position ids (N,) and the
/// scan-position table (K, 8): id, origin x y z, sigma_range, sigma_range_ppm, sigma_scan, sigma_yaw.
m3c2::CloudUncertainty cloud_uncertainty(const std::optional<Points>& precision, const std::optional<Ids>& ids,
                                         const std::optional<Table>& table) {
  m3c2::CloudUncertainty c;
  if (precision) c.precision = {precision->data(), 3 * precision->shape(0)};
  if (ids) c.scan_position = {ids->data(), ids->shape(0)};
  if (table)
    for (std::size_t k = 0; k < table->shape(0); ++k) {
      const double* row = table->data() + 8 * k;
      if (!(row[0] >= 0.0 && row[0] <= 16777216.0 && row[0] == std::floor(row[0])))
        throw m3c2::InvalidArgument("scan-position ids must be integers in [0, 2^24]");
      m3c2::ScanPosition sp;
      sp.id = static_cast<std::uint32_t>(row[0]);
      for (int a = 0; a < 3; ++a) sp.origin[a] = row[1 + a];
      sp.sigma_range = row[4], sp.sigma_range_ppm = row[5], sp.sigma_scan = row[6], sp.sigma_yaw = row[7];
      c.scan_positions.push_back(sp);
    }
  return c;
}

void copy_exact(const char* what, const std::optional<Flat>& a, std::size_t count, double* out) {
  if (!a) return;
  if (a->size() != count)
    throw m3c2::InvalidArgument(std::string(what) + " must hold " + std::to_string(count) + " values, got " +
                                std::to_string(a->size()));
  std::copy(a->data(), a->data() + count, out);
}

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
  if (!r.spread1.empty()) {
    d["spread1"] = to_numpy(std::move(r.spread1));
    d["spread2"] = to_numpy(std::move(r.spread2));
  }
  if (!r.covariance1.empty()) {
    const std::size_t n = r.covariance1.size() / 9;
    auto* c1 = new std::vector<double>(std::move(r.covariance1));
    auto* c2 = new std::vector<double>(std::move(r.covariance2));
    nb::capsule o1(c1, [](void* p) noexcept { delete static_cast<std::vector<double>*>(p); });
    nb::capsule o2(c2, [](void* p) noexcept { delete static_cast<std::vector<double>*>(p); });
    d["covariance1"] = nb::ndarray<nb::numpy, double>(c1->data(), {n, 3, 3}, o1);
    d["covariance2"] = nb::ndarray<nb::numpy, double>(c2->data(), {n, 3, 3}, o2);
  }
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
  nb::enum_<m3c2::Lod>(m, "Lod")
      .value("z", m3c2::Lod::kZ)
      .value("t", m3c2::Lod::kT)
      .value("auto", m3c2::Lod::kAuto)
      .value("bootstrap", m3c2::Lod::kBootstrap);
  nb::enum_<m3c2::MedianLod>(m, "MedianLod")
      .value("maritz_jarrett", m3c2::MedianLod::kMaritzJarrett)
      .value("cloudcompare", m3c2::MedianLod::kCloudCompare);

  nb::enum_<m3c2::Uncertainty>(m, "Uncertainty")
      .value("eq1", m3c2::Uncertainty::kEq1)
      .value("pm", m3c2::Uncertainty::kPrecisionMaps)
      .value("ep", m3c2::Uncertainty::kErrorPropagation);
  nb::enum_<m3c2::PrecisionRule>(m, "PrecisionRule")
      .value("nearest", m3c2::PrecisionRule::kNearest)
      .value("all", m3c2::PrecisionRule::kAllPoints);
  nb::enum_<m3c2::EpCovariance>(m, "EpCovariance")
      .value("independent", m3c2::EpCovariance::kIndependent)
      .value("mean_of_points", m3c2::EpCovariance::kMeanOfPoints);
  nb::enum_<m3c2::EpWeights>(m, "EpWeights")
      .value("normal", m3c2::EpWeights::kNormal)
      .value("matrix", m3c2::EpWeights::kMatrix);
  nb::enum_<m3c2::EpLod>(m, "EpLod")
      .value("projected", m3c2::EpLod::kProjected)
      .value("published", m3c2::EpLod::kPublished);

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
      .def_rw("lod", &m3c2::Params::lod)
      .def_rw("median_lod", &m3c2::Params::median_lod)
      // The legacy switches of --t-statistic and --bootstrap N, mapped onto `lod`: t_statistic
      // True is the paper's rule (Lod.auto), False leaves `lod` alone; bootstrap_samples > 0 also
      // selects Lod.bootstrap (0 leaves `lod` alone).
      .def_prop_rw(
          "t_statistic", [](const m3c2::Params& p) { return p.lod == m3c2::Lod::kAuto; },
          [](m3c2::Params& p, bool on) {
            if (on) p.lod = m3c2::Lod::kAuto;
          })
      .def_prop_rw(
          "bootstrap_samples", [](const m3c2::Params& p) { return p.bootstrap_samples; },
          [](m3c2::Params& p, std::uint32_t n) {
            p.bootstrap_samples = n;
            if (n > 0) p.lod = m3c2::Lod::kBootstrap;
          })
      .def_rw("bootstrap_seed", &m3c2::Params::bootstrap_seed)
      .def_rw("uncertainty", &m3c2::Params::uncertainty)
      .def_rw("precision_rule", &m3c2::Params::precision_rule)
      .def_rw("precision_scale1", &m3c2::Params::precision_scale1)
      .def_rw("precision_scale2", &m3c2::Params::precision_scale2)
      .def_rw("ep_covariance", &m3c2::Params::ep_covariance)
      .def_rw("ep_lod", &m3c2::Params::ep_lod)
      .def_rw("ep_weights", &m3c2::Params::ep_weights);

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
         std::optional<Points> core_normals, int threads, nb::object progress, std::optional<Points> precision1,
         std::optional<Points> precision2, std::optional<Ids> scan_position1, std::optional<Ids> scan_position2,
         std::optional<Table> scan_positions1, std::optional<Table> scan_positions2, std::optional<Flat> transform,
         std::optional<Flat> alignment_covariance, std::optional<Flat> reduction_point, bool transform_applied,
         bool covariances) {
        std::vector<double> normals;
        if (core_normals) normals.assign(core_normals->data(), core_normals->data() + 3 * core_normals->shape(0));
        // Per-point uncertainty inputs (include/m3c2/uncertainty.hpp), viewed, not copied.
        m3c2::UncertaintyInputs u;
        u.reference = cloud_uncertainty(precision1, scan_position1, scan_positions1);
        u.compared = cloud_uncertainty(precision2, scan_position2, scan_positions2);
        copy_exact("transform (3x4)", transform, 12, u.transform);
        if (alignment_covariance) {
          u.alignment_covariance.resize(144);
          copy_exact("alignment covariance (12x12)", alignment_covariance, 144, u.alignment_covariance.data());
        }
        copy_exact("reduction point", reduction_point, 3, u.reduction_point);
        u.transform_applied = transform_applied;
        u.covariances = covariances;
        return result_dict(run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::compute(view(reference), view(compared), view(core), params, run, normals, u);
        }));
      },
      "reference"_a, "compared"_a, "core_points"_a, "params"_a, "core_normals"_a = nb::none(), "threads"_a = 0,
      "progress"_a = nb::none(), "precision1"_a = nb::none(), "precision2"_a = nb::none(),
      "scan_position1"_a = nb::none(), "scan_position2"_a = nb::none(), "scan_positions1"_a = nb::none(),
      "scan_positions2"_a = nb::none(), "transform"_a = nb::none(), "alignment_covariance"_a = nb::none(),
      "reduction_point"_a = nb::none(), "transform_applied"_a = false, "covariances"_a = false);

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

  // Multi-scale dimensionality of Brodu & Lague 2012 (CANUPO; include/m3c2/dimensionality.hpp).
  m.def(
      "dimensionality",
      [](const Points& cloud, const Points& core, const std::vector<double>& diameters, std::uint32_t min_points,
         int threads, nb::object progress) {
        m3c2::DimensionalityResult r = run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::dimensionality(view(cloud), view(core), diameters, min_points, run);
        });
        const std::size_t n = r.size(), s = r.scales;
        nb::dict d;
        d["status"] = status_array(r.status);
        auto per_scale3 = [&](std::vector<double>&& v) {
          auto* owned = new std::vector<double>(std::move(v));
          nb::capsule owner(owned, [](void* p) noexcept { delete static_cast<std::vector<double>*>(p); });
          return nb::ndarray<nb::numpy, double>(owned->data(), {n, s, 3}, owner);
        };
        d["proportions"] = per_scale3(std::move(r.proportions));
        d["barycentric"] = per_scale3(std::move(r.barycentric));
        d["count"] = to_numpy(std::move(r.count), s);
        return d;
      },
      "cloud"_a, "core_points"_a, "diameters"_a, "min_points"_a = 3, "threads"_a = 0, "progress"_a = nb::none());
}
