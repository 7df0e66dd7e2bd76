// The thin binding: numpy arrays in (viewed, not copied, when float64 and C-contiguous),
// the GIL released while the engine runs, numpy arrays out (the engine's vectors, not copied):
// support.hpp. PB-M3C2's functions are bound in pbm3c2.cpp.

#include <m3c2/cylinder_index.hpp>
#include <m3c2/kalman.hpp>
#include <m3c2/m3c2.hpp>
#include <m3c2/objects_by_change.hpp>
#include <m3c2/region_covariance.hpp>
#include <m3c2/registration.hpp>
#include <m3c2/series.hpp>
#include <m3c2/tam3c2.hpp>
#include <m3c2/variogram.hpp>

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/array.h>
#include <nanobind/stl/function.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <optional>
#include <type_traits>

namespace nb = nanobind;
using namespace nb::literals;

#include "support.hpp"

namespace {

using namespace m3c2::binding;

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

/// compute()'s per-point uncertainty inputs as Python gives them (m3c2kit.run.uncertainty_inputs),
/// one bound object instead of eleven arguments: the arrays are held, and viewed while compute runs.
struct UncertaintyArrays {
  std::optional<Points> precision1, precision2;
  std::optional<Ids> scan_position1, scan_position2;
  std::optional<Table> scan_positions1, scan_positions2;
  std::optional<Flat> transform, alignment_covariance, reduction_point;
  bool transform_applied = false, covariances = false;
};

void copy_exact(const char* what, const std::optional<Flat>& a, std::size_t count, double* out) {
  if (!a) return;
  if (a->size() != count)
    throw m3c2::InvalidArgument(std::string(what) + " must hold " + std::to_string(count) + " values, got " +
                                std::to_string(a->size()));
  std::copy(a->data(), a->data() + count, out);
}

nb::ndarray<nb::numpy, std::uint8_t> column_array(std::vector<m3c2::PointStatus>&& s, std::size_t) {
  return status_array(s);
}

/// A Result column as numpy: (n,), (n, width), or (n, 3, 3) for the 9 values of a 3x3 matrix.
template <class T>
nb::ndarray<nb::numpy, T> column_array(std::vector<T>&& values, std::size_t width) {
  if (width != 9) return to_numpy(std::move(values), width);
  auto* owned = new std::vector<T>(std::move(values));
  nb::capsule owner(owned, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
  return nb::ndarray<nb::numpy, T>(owned->data(), {owned->size() / 9, 3, 3}, owner);
}

nb::dict result_dict(m3c2::Result&& r) {
  nb::dict d;
  m3c2::visit_result_fields(r, [&](const char* name, auto& column, std::size_t width, bool optional) {
    if (!optional || !column.empty()) d[name] = column_array(std::move(column), width);
  });
  return d;
}

/// Names of the Result columns that are always present (`optional` false) or only with some
/// parameters (`optional` true).
std::vector<std::string> result_fields(bool optional) {
  std::vector<std::string> names;
  m3c2::Result r;
  m3c2::visit_result_fields(r, [&](const char* name, auto&, std::size_t, bool is_optional) {
    if (is_optional == optional) names.emplace_back(name);
  });
  return names;
}

/// The type of the Params field that `access` reaches.
template <class Access>
using FieldType = std::remove_reference_t<std::invoke_result_t<Access, m3c2::Params&>>;

/// Params as a Python class whose properties and pickled state come from m3c2::visit_param_fields,
/// so that a new field of the struct needs no edit here (docs/architecture.md).
void bind_params(nb::module_& m) {
  nb::class_<m3c2::Params> cls(m, "Params");
  cls.def(nb::init<>());
  std::vector<std::string> names;
  m3c2::visit_param_fields([&](const char* name, auto access) {
    using T = FieldType<decltype(access)>;
    cls.def_prop_rw(
        name, [access](const m3c2::Params& p) -> T { return access(p); },
        [access](m3c2::Params& p, const T& value) { access(p) = value; });
    names.emplace_back(name);
  });
  cls.def("__getstate__", [](const m3c2::Params& p) {
    nb::dict state;
    m3c2::visit_param_fields([&](const char* name, auto access) { state[name] = nb::cast(access(p)); });
    return state;
  });
  cls.def("__setstate__", [](m3c2::Params& p, const nb::dict& state) {
    new (&p) m3c2::Params();
    m3c2::visit_param_fields([&](const char* name, auto access) {
      using T = FieldType<decltype(access)>;
      if (state.contains(name)) access(p) = nb::cast<T>(state[name]);
    });
  });
  m.attr("PARAM_FIELDS") = nb::cast(names);
}

}  // namespace

namespace m3c2::binding {
void bind_pbm3c2(nb::module_& m);  // pbm3c2.cpp
}  // namespace m3c2::binding

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
      .value("cloudcompare", m3c2::ScaleSelection::kCloudCompare)
      .value("py4dgeo", m3c2::ScaleSelection::kPy4dgeo);
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
      .value("mean_of_points", m3c2::EpCovariance::kMeanOfPoints)
      .value("empirical", m3c2::EpCovariance::kEmpirical);
  nb::enum_<m3c2::EpWeights>(m, "EpWeights")
      .value("normal", m3c2::EpWeights::kNormal)
      .value("matrix", m3c2::EpWeights::kMatrix);
  nb::enum_<m3c2::EpLod>(m, "EpLod")
      .value("projected", m3c2::EpLod::kProjected)
      .value("published", m3c2::EpLod::kPublished);

  bind_params(m);
  m.attr("RESULT_FIELDS") = nb::cast(result_fields(false));
  m.attr("OPTIONAL_RESULT_FIELDS") = nb::cast(result_fields(true));

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
  m.def("neighbourhood_reach", &m3c2::neighbourhood_reach, "params"_a,
        "Largest distance from a core point to a point that can change its result.");
  m.def("tile_halo", &m3c2::tile_halo, "params"_a, "The halo a tile of core points needs.");
  m.def(
      "fdr_q_values",
      [](const nb::ndarray<const double, nb::ndim<1>, nb::c_contig, nb::device::cpu>& p, const std::string& method) {
        if (method != "bh" && method != "by") throw m3c2::InvalidArgument("fdr method must be bh or by, got " + method);
        const auto kind = method == "bh" ? m3c2::FdrMethod::kBenjaminiHochberg : m3c2::FdrMethod::kBenjaminiYekutieli;
        std::vector<double> q;
        const std::span<const double> values(p.data(), p.shape(0));
        {
          nb::gil_scoped_release release;
          q = m3c2::fdr_q_values(values, kind);
        }
        return to_numpy(std::move(q));
      },
      "p"_a, "method"_a, "Benjamini-Hochberg (bh) or -Yekutieli (by) adjusted p-values; NaN where p is NaN.");
  m.attr("MAX_CELLS_PER_AXIS") = m3c2::kMaxCellsPerAxis;
  m.def("index_memory", [] {
    const m3c2::IndexMemory mem = m3c2::index_memory();
    nb::dict d;
    d["bytes_per_point"] = mem.bytes_per_point, d["copy_bytes_per_point"] = mem.copy_bytes_per_point;
    d["moments_bytes_per_point"] = mem.moments_bytes_per_point;
    d["overhead"] = mem.overhead, d["bytes_per_core_point"] = mem.bytes_per_core_point;
    return d;
  });
  m.def("memory_estimate", &m3c2::memory_estimate, "n_reference"_a, "n_compared"_a, "n_core"_a, "params"_a,
        "order_clouds_in_place"_a = false,
        "Bytes compute() allocates beyond its inputs for clouds of these sizes (an upper estimate).");

  nb::class_<UncertaintyArrays>(m, "UncertaintyArrays")
      .def(nb::init<>())
      .def_rw("precision1", &UncertaintyArrays::precision1, nb::arg("value").none())
      .def_rw("precision2", &UncertaintyArrays::precision2, nb::arg("value").none())
      .def_rw("scan_position1", &UncertaintyArrays::scan_position1, nb::arg("value").none())
      .def_rw("scan_position2", &UncertaintyArrays::scan_position2, nb::arg("value").none())
      .def_rw("scan_positions1", &UncertaintyArrays::scan_positions1, nb::arg("value").none())
      .def_rw("scan_positions2", &UncertaintyArrays::scan_positions2, nb::arg("value").none())
      .def_rw("transform", &UncertaintyArrays::transform, nb::arg("value").none())
      .def_rw("alignment_covariance", &UncertaintyArrays::alignment_covariance, nb::arg("value").none())
      .def_rw("reduction_point", &UncertaintyArrays::reduction_point, nb::arg("value").none())
      .def_rw("transform_applied", &UncertaintyArrays::transform_applied)
      .def_rw("covariances", &UncertaintyArrays::covariances);

  m.def(
      "compute",
      [](const Points& reference, const Points& compared, const Points& core, const m3c2::Params& params,
         std::optional<Points> core_normals, int threads, nb::object progress, const UncertaintyArrays& inputs,
         bool order_in_place) {
        std::vector<double> normals;
        if (core_normals) normals.assign(core_normals->data(), core_normals->data() + 3 * core_normals->shape(0));
        // Per-point uncertainty inputs (include/m3c2/uncertainty.hpp), viewed, not copied.
        m3c2::UncertaintyInputs u;
        u.reference = cloud_uncertainty(inputs.precision1, inputs.scan_position1, inputs.scan_positions1);
        u.compared = cloud_uncertainty(inputs.precision2, inputs.scan_position2, inputs.scan_positions2);
        copy_exact("transform (3x4)", inputs.transform, 12, u.transform);
        if (inputs.alignment_covariance) {
          u.alignment_covariance.resize(144);
          copy_exact("alignment covariance (12x12)", inputs.alignment_covariance, 144, u.alignment_covariance.data());
        }
        copy_exact("reduction point", inputs.reduction_point, 3, u.reduction_point);
        u.transform_applied = inputs.transform_applied;
        u.covariances = inputs.covariances;
        return result_dict(run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
          // order_in_place: the caller vouches that both arrays are its own and writeable
          // (m3c2kit.run.in_memory decides; RunOptions::order_clouds_in_place).
          m3c2::RunOptions with_order = run;
          with_order.order_clouds_in_place = order_in_place;
          return m3c2::compute(view(reference), view(compared), view(core), params, with_order, normals, u);
        }));
      },
      "reference"_a, "compared"_a, "core_points"_a, "params"_a, "core_normals"_a = nb::none(), "threads"_a = 0,
      "progress"_a = nb::none(), "uncertainty"_a = UncertaintyArrays{}, "order_in_place"_a = false);

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
      "variogram_pairs",
      [](const Points& points, const Values& values_array, const std::vector<double>& edges, std::uint64_t seed,
         std::uint64_t centres, double near_radius, std::uint32_t max_neighbours, std::uint64_t far_pairs, bool planar,
         int threads, nb::object progress) {
        const m3c2::VariogramSampling sampling{seed, centres, near_radius, max_neighbours, far_pairs, planar};
        const std::vector<double> values(values_array.data(), values_array.data() + values_array.shape(0));
        m3c2::VariogramSums r = run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::variogram_pairs(view(points), values, edges, sampling, run);
        });
        nb::dict d;
        d["pairs"] = to_numpy(std::move(r.pairs));
        d["lag_sum"] = to_numpy(std::move(r.lag_sum));
        d["half_sq_sum"] = to_numpy(std::move(r.half_sq_sum));
        return d;
      },
      "points"_a, "values"_a, "edges"_a, "seed"_a, "centres"_a, "near_radius"_a, "max_neighbours"_a, "far_pairs"_a,
      "planar"_a, "threads"_a = 0, "progress"_a = nb::none());

  // sum_i sum_j C(|x_i - x_j|) of an error model's correlated components over a region's points
  // (include/m3c2/region_covariance.hpp): by bins, or exactly (O(N^2), for tests)
  using PlanPoints = nb::ndarray<const double, nb::shape<-1, 2>, nb::c_contig, nb::device::cpu>;
  const auto covariance_components = [](const std::vector<std::uint8_t>& kinds, const std::vector<double>& sills,
                                        const std::vector<double>& ranges) {
    if (kinds.size() != sills.size() || kinds.size() != ranges.size())
      throw m3c2::InvalidArgument("components: kinds, sills and ranges differ in length");
    std::vector<m3c2::CovarianceComponent> out;
    for (std::size_t k = 0; k < kinds.size(); ++k)
      out.push_back({static_cast<m3c2::CovarianceKind>(kinds[k]), sills[k], ranges[k]});
    return out;
  };
  m.def(
      "component_values",
      [covariance_components](std::uint8_t kind, double sill, double range, const Values& h, bool variogram) {
        const auto component = covariance_components({kind}, {sill}, {range}).front();
        std::vector<double> out(h.shape(0));
        for (std::size_t i = 0; i < out.size(); ++i)
          out[i] = variogram ? m3c2::component_variogram(component, h.data()[i])
                             : m3c2::component_covariance(component, h.data()[i]);
        return to_numpy(std::move(out));
      },
      "kind"_a, "sill"_a, "range"_a, "h"_a, "variogram"_a = false,
      "C(h) of one component at the lags h, or gamma(h) with variogram=True (region_covariance.hpp).");
  m.def(
      "region_covariance_sum",
      [covariance_components](const PlanPoints& xy, const std::vector<std::uint8_t>& kinds,
                              const std::vector<double>& sills, const std::vector<double>& ranges, double bin_fraction,
                              double exponential_reach, int threads, nb::object progress) {
        const auto components = covariance_components(kinds, sills, ranges);
        m3c2::CovarianceSumOptions options;
        options.bin_fraction = bin_fraction;
        options.exponential_reach = exponential_reach;
        const std::span<const double> flat(xy.data(), 2 * xy.shape(0));
        m3c2::CovarianceSum r = run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::region_covariance_sum(flat, components, options, run);
        });
        return nb::make_tuple(r.sum, r.bin_side);
      },
      "xy"_a, "kinds"_a, "sills"_a, "ranges"_a, "bin_fraction"_a = 0.125, "exponential_reach"_a = 4.0, "threads"_a = 0,
      "progress"_a = nb::none());
  m.def(
      "region_covariance_exact",
      [covariance_components](const PlanPoints& xy, const std::vector<std::uint8_t>& kinds,
                              const std::vector<double>& sills, const std::vector<double>& ranges, int threads,
                              nb::object progress) {
        const auto components = covariance_components(kinds, sills, ranges);
        const std::span<const double> flat(xy.data(), 2 * xy.shape(0));
        return run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::region_covariance_exact(flat, components, run);
        });
      },
      "xy"_a, "kinds"_a, "sills"_a, "ranges"_a, "threads"_a = 0, "progress"_a = nb::none());

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
      "match_rows",
      [](const Points& points, const Points& queries) -> std::optional<nb::ndarray<nb::numpy, std::uint64_t>> {
        std::optional<std::vector<std::uint64_t>> found;
        {
          nb::gil_scoped_release nogil;
          found = m3c2::match_rows(view(points), view(queries));
        }
        if (!found) return std::nullopt;
        return to_numpy(std::move(*found));
      },
      "points"_a, "queries"_a);

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

  // Point-to-plane ICP on stable areas (include/m3c2/registration.hpp, docs/registration.md).
  nb::class_<m3c2::RegistrationParams>(m, "RegistrationParams")
      .def(nb::init<>())
      .def_rw("normal_diameter", &m3c2::RegistrationParams::normal_diameter)
      .def_rw("max_distance", &m3c2::RegistrationParams::max_distance)
      .def_rw("reject", &m3c2::RegistrationParams::reject)
      .def_rw("max_iterations", &m3c2::RegistrationParams::max_iterations)
      .def_rw("tolerance", &m3c2::RegistrationParams::tolerance)
      .def_rw("min_pairs", &m3c2::RegistrationParams::min_pairs)
      .def_rw("max_points", &m3c2::RegistrationParams::max_points);
  m.def(
      "register_clouds",
      [](const Points& reference, const Points& compared, const m3c2::RegistrationParams& params, int threads,
         nb::object progress) {
        const m3c2::Registration r = run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::register_clouds(view(reference), view(compared), params, run);
        });
        nb::dict d;
        d["matrix"] = std::vector<double>(r.matrix.begin(), r.matrix.end());
        d["covariance"] = std::vector<double>(r.covariance.begin(), r.covariance.end());
        d["centre"] = std::vector<double>(r.centre.begin(), r.centre.end());
        d["registration_error"] = r.registration_error, d["rms"] = r.rms;
        d["pairs"] = r.pairs, d["candidates"] = r.candidates;
        d["iterations"] = r.iterations, d["converged"] = r.converged;
        return d;
      },
      "reference"_a, "compared"_a, "params"_a, "threads"_a = 0, "progress"_a = nb::none());

  // C2C baselines of section 3.4 (include/m3c2/baselines.hpp, docs/analysis.md).
  m.def(
      "c2c",
      [](const Points& reference, const Points& compared, const std::string& model, double model_radius,
         std::uint32_t model_neighbours, const std::string& rule, int threads, nb::object progress) {
        m3c2::C2CParams p;
        if (model == "none")
          p.model = m3c2::LocalModel::kNone;
        else if (model == "plane")
          p.model = m3c2::LocalModel::kPlane;
        else
          throw m3c2::InvalidArgument("model must be 'none' or 'plane', got '" + model + "'");
        if (rule == "closer")
          p.rule = m3c2::ModelRule::kCloser;
        else if (rule == "model")
          p.rule = m3c2::ModelRule::kModelOnly;
        else
          throw m3c2::InvalidArgument("rule must be 'closer' or 'model', got '" + rule + "'");
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

  // One cloud queried with cylinders of several diameters (include/m3c2/cylinder_index.hpp, the
  // data-quality diagnosis); the cloud's array is kept alive by the object.
  struct CloudCylinders {
    nb::object cloud;  // the engine reads the cloud's coordinates in place
    std::optional<m3c2::CylinderIndex> index;
  };
  nb::class_<CloudCylinders>(m, "CylinderIndex")
      .def(
          "__init__",
          [](CloudCylinders* self, const Points& cloud, double smallest_diameter, int threads) {
            new (self) CloudCylinders{nb::cast(cloud), std::nullopt};
            self->index.emplace(run_engine(nb::none(), threads, [&](const m3c2::RunOptions& run) {
              return m3c2::CylinderIndex(view(cloud), smallest_diameter, run);
            }));
          },
          "cloud"_a, "smallest_diameter"_a, "threads"_a = 0)
      .def(
          "statistics",
          [](const CloudCylinders& self, const Points& core, const Points& normals, double diameter, double half_length,
             int threads) {
            const std::vector<double> axes(normals.data(), normals.data() + 3 * normals.shape(0));
            m3c2::CylinderStatistics c = run_engine(nb::none(), threads, [&](const m3c2::RunOptions& run) {
              return self.index->statistics(view(core), axes, diameter, half_length, run);
            });
            nb::dict d;
            d["count"] = to_numpy(std::move(c.count));
            d["mean"] = to_numpy(std::move(c.mean));
            d["sigma"] = to_numpy(std::move(c.sigma));
            return d;
          },
          "core_points"_a, "normals"_a, "diameter"_a, "half_length"_a, "threads"_a = 0);

  // Time series (include/m3c2/series.hpp, docs/series.md): the reference prepared once, one
  // epoch compared at a time; the reference array is kept alive by the object.
  struct SeriesComparison {
    nb::object reference;  // the engine reads the reference's coordinates in place
    std::optional<m3c2::Comparison> comparison;
  };
  nb::class_<SeriesComparison>(m, "Comparison")
      .def(
          "__init__",
          [](SeriesComparison* self, const Points& reference, const Points& core, const m3c2::Params& params,
             std::optional<Points> core_normals, int threads, nb::object progress) {
            std::vector<double> normals;
            if (core_normals) normals.assign(core_normals->data(), core_normals->data() + 3 * core_normals->shape(0));
            new (self) SeriesComparison{nb::cast(reference), std::nullopt};
            self->comparison.emplace(run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
              return m3c2::Comparison(view(reference), view(core), params, run, normals);
            }));
          },
          "reference"_a, "core_points"_a, "params"_a, "core_normals"_a = nb::none(), "threads"_a = 0,
          "progress"_a = nb::none())
      .def(
          "compare",
          [](const SeriesComparison& self, const Points& compared, int threads, nb::object progress) {
            return result_dict(run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
              return self.comparison->compare(view(compared), run);
            }));
          },
          "compared"_a, "threads"_a = 0, "progress"_a = nb::none())
      .def("normals",
           [](const SeriesComparison& self) {
             m3c2::NormalsResult r = self.comparison->normals();
             nb::dict d;
             d["status"] = status_array(r.status);
             d["normal"] = to_numpy(std::move(r.normal), 3);
             d["normal_scale"] = to_numpy(std::move(r.normal_scale));
             d["roughness"] = to_numpy(std::move(r.roughness));
             return d;
           })
      .def("__len__", [](const SeriesComparison& self) { return self.comparison->size(); });

  // Analysis of a series (include/m3c2/objects_by_change.hpp): smoothing, change points, 4D-OBC.
  using Series2D = nb::ndarray<const double, nb::ndim<2>, nb::c_contig, nb::device::cpu>;
  using Series1D = nb::ndarray<const double, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
  nb::enum_<m3c2::ObjectsDtw>(m, "ObjectsDtw")
      .value("baseline", m3c2::ObjectsDtw::kBaseline)
      .value("seed_start", m3c2::ObjectsDtw::kSeedStart)
      .value("py4dgeo", m3c2::ObjectsDtw::kPy4dgeo);
  nb::class_<m3c2::ObjectsParams>(m, "ObjectsParams")
      .def(nb::init<>())
      .def_prop_rw(
          "window_width", [](const m3c2::ObjectsParams& p) { return p.change_points.width; },
          [](m3c2::ObjectsParams& p, std::uint32_t v) { p.change_points.width = v; })
      .def_prop_rw(
          "window_min_size", [](const m3c2::ObjectsParams& p) { return p.change_points.min_size; },
          [](m3c2::ObjectsParams& p, std::uint32_t v) { p.change_points.min_size = v; })
      .def_prop_rw(
          "window_jump", [](const m3c2::ObjectsParams& p) { return p.change_points.jump; },
          [](m3c2::ObjectsParams& p, std::uint32_t v) { p.change_points.jump = v; })
      .def_prop_rw(
          "window_penalty", [](const m3c2::ObjectsParams& p) { return p.change_points.penalty; },
          [](m3c2::ObjectsParams& p, double v) { p.change_points.penalty = v; })
      .def_rw("min_period", &m3c2::ObjectsParams::min_period)
      .def_rw("height_threshold", &m3c2::ObjectsParams::height_threshold)
      .def_rw("use_unfinished", &m3c2::ObjectsParams::use_unfinished)
      .def_rw("seed_subsampling", &m3c2::ObjectsParams::seed_subsampling)
      .def_rw("neighbourhood_radius", &m3c2::ObjectsParams::neighbourhood_radius)
      .def_rw("thresholds", &m3c2::ObjectsParams::thresholds)
      .def_rw("min_segments", &m3c2::ObjectsParams::min_segments)
      .def_rw("max_segments", &m3c2::ObjectsParams::max_segments)
      .def_rw("max_cv", &m3c2::ObjectsParams::max_cv)
      .def_rw("dtw", &m3c2::ObjectsParams::dtw)
      .def_rw("neighbour_table_bytes", &m3c2::ObjectsParams::neighbour_table_bytes);

  m.def(
      "temporal_median",
      [](const Series2D& values, std::uint32_t window, int threads) {
        const std::size_t rows = values.shape(0), epochs = values.shape(1);
        auto out = run_engine(nb::none(), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::temporal_median(values.data(), rows, epochs, window, run);
        });
        return to_numpy(std::move(out), epochs);
      },
      "values"_a, "window"_a, "threads"_a = 0);
  m.def(
      "change_points",
      [](const Series1D& series, std::uint32_t width, std::uint32_t min_size, std::uint32_t jump, double penalty) {
        m3c2::ChangePointParams p{width, min_size, jump, penalty};
        return to_numpy(m3c2::change_points(series.data(), series.shape(0), p));
      },
      "series"_a, "width"_a = 24, "min_size"_a = 12, "jump"_a = 1, "penalty"_a = 1.0);
  m.def(
      "normalised_dtw",
      [](const Series1D& a, const Series1D& b, double norm_a, double norm_b, double dmax_origin) {
        if (a.shape(0) != b.shape(0)) throw m3c2::InvalidArgument("the two series must have the same length");
        return m3c2::normalised_dtw(a.data(), b.data(), a.shape(0), norm_a, norm_b, dmax_origin);
      },
      "a"_a, "b"_a, "norm_a"_a = 0.0, "norm_b"_a = 0.0, "dmax_origin"_a = 0.0);
  m.def(
      "objects_by_change",
      [](const Series2D& distances, const Points& core, const m3c2::ObjectsParams& params, int threads,
         nb::object progress) {
        m3c2::ObjectsResult r = run_engine(std::move(progress), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::objects_by_change(distances.data(), distances.shape(0), distances.shape(1), view(core), params,
                                         run);
        });
        std::vector<std::uint32_t> seed_core, seed_start, seed_end, seed_base, obj_core, obj_start, obj_end, obj_base,
            members;
        std::vector<std::uint64_t> offsets{0};
        std::vector<double> seed_score, obj_threshold, obj_score, dtw;
        for (const auto& s : r.seeds)
          seed_core.push_back(s.core), seed_start.push_back(s.start), seed_end.push_back(s.end),
              seed_base.push_back(s.base), seed_score.push_back(s.score);
        for (const auto& o : r.objects) {
          obj_core.push_back(o.seed.core), obj_start.push_back(o.seed.start), obj_end.push_back(o.seed.end),
              obj_base.push_back(o.seed.base);
          obj_threshold.push_back(o.threshold), obj_score.push_back(o.seed.score);
          members.insert(members.end(), o.cores.begin(), o.cores.end());
          dtw.insert(dtw.end(), o.dtw.begin(), o.dtw.end());
          offsets.push_back(members.size());
        }
        nb::dict d;
        d["seed_core"] = to_numpy(std::move(seed_core)), d["seed_start"] = to_numpy(std::move(seed_start));
        d["seed_end"] = to_numpy(std::move(seed_end)), d["seed_score"] = to_numpy(std::move(seed_score));
        d["seed_base"] = to_numpy(std::move(seed_base)), d["object_base"] = to_numpy(std::move(obj_base));
        d["object_seed"] = to_numpy(std::move(obj_core)), d["object_start"] = to_numpy(std::move(obj_start));
        d["object_end"] = to_numpy(std::move(obj_end)), d["object_threshold"] = to_numpy(std::move(obj_threshold));
        d["object_score"] = to_numpy(std::move(obj_score)), d["member_offsets"] = to_numpy(std::move(offsets));
        d["members"] = to_numpy(std::move(members)), d["member_dtw"] = to_numpy(std::move(dtw));
        return d;
      },
      "distances"_a, "core_points"_a, "params"_a, "threads"_a = 0, "progress"_a = nb::none());

  // The Kalman filter and RTS smoother of a series (include/m3c2/kalman.hpp).
  using Moments = nb::ndarray<double, nb::ndim<3>, nb::c_contig, nb::device::cpu>;
  nb::class_<m3c2::KalmanParams>(m, "KalmanParams")
      .def(nb::init<>())
      .def_prop_rw(
          "order", [](const m3c2::KalmanParams& p) { return int(p.model); },
          [](m3c2::KalmanParams& p, int v) {
            if (v != 2 && v != 3) throw m3c2::InvalidArgument("the Kalman state's order must be 2 or 3");
            p.model = m3c2::KalmanModel(v);
          })
      .def_prop_rw(
          "discrete_noise", [](const m3c2::KalmanParams& p) { return p.noise == m3c2::KalmanNoise::kDiscrete; },
          [](m3c2::KalmanParams& p, bool v) {
            p.noise = v ? m3c2::KalmanNoise::kDiscrete : m3c2::KalmanNoise::kContinuous;
          })
      .def_rw("process_noise", &m3c2::KalmanParams::process_noise)
      .def_rw("prior_given", &m3c2::KalmanParams::prior_given)
      .def_rw("prior_time", &m3c2::KalmanParams::prior_time)
      .def_rw("initial_variance", &m3c2::KalmanParams::initial_variance)
      .def_prop_rw(
          "observation",
          [](const m3c2::KalmanParams& p) {
            return p.observation == m3c2::KalmanObservation::kShared ? "shared" : "independent";
          },
          [](m3c2::KalmanParams& p, const std::string& v) {
            if (v != "shared" && v != "independent")
              throw m3c2::InvalidArgument("the observation model must be shared or independent, got " + v);
            p.observation = v == "shared" ? m3c2::KalmanObservation::kShared : m3c2::KalmanObservation::kIndependent;
          })
      .def_rw("reference_time", &m3c2::KalmanParams::reference_time)
      .def_rw("reference_epoch", &m3c2::KalmanParams::reference_epoch)
      .def_rw("registration_error", &m3c2::KalmanParams::registration_error)
      .def_rw("step_false_alarm", &m3c2::KalmanParams::step_false_alarm)
      .def_prop_rw(
          "population_spread", [](const m3c2::KalmanParams& p) { return p.spread == m3c2::Variance::kPopulation; },
          [](m3c2::KalmanParams& p, bool v) { p.spread = v ? m3c2::Variance::kPopulation : m3c2::Variance::kSample; });
  // The shared model's inputs (core x epoch each): sigma1, n1, sigma2, n2, as the store keeps them.
  using Spread = std::optional<std::tuple<Series2D, Series2D, Series2D, Series2D>>;
  const auto kalman_block = [](const Series2D& values, const std::optional<Series2D>& variance, const Series1D& times,
                               std::size_t resume_from, const std::optional<Series2D>& prior_mean,
                               const Spread& spread) {
    const std::size_t rows = values.shape(0), epochs = values.shape(1);
    const auto agrees = [&](const Series2D& a) { return a.shape(0) == rows && a.shape(1) == epochs; };
    if ((variance && !agrees(*variance)) || times.shape(0) != epochs)
      throw m3c2::InvalidArgument("values, variances (core x epoch) and times (epoch) must agree in shape");
    m3c2::KalmanBlock b;
    b.values = values.data(), b.variance = variance ? variance->data() : nullptr, b.times = times.data();
    b.rows = rows, b.epochs = epochs, b.resume_from = resume_from;
    if (prior_mean) {
      if (prior_mean->shape(0) != rows) throw m3c2::InvalidArgument("prior_mean must have a row per core point");
      b.prior_mean = prior_mean->data();
    }
    if (spread) {
      const auto& [s1, n1, s2, n2] = *spread;
      if (!agrees(s1) || !agrees(n1) || !agrees(s2) || !agrees(n2))
        throw m3c2::InvalidArgument("sigma1, n1, sigma2 and n2 must be core x epoch, as the values");
      b.sigma1 = s1.data(), b.n1 = n1.data(), b.sigma2 = s2.data(), b.n2 = n2.data();
    }
    return b;
  };
  m.def(
      "kalman_smooth",
      [kalman_block](const Series2D& values, const std::optional<Series2D>& variance, const Series1D& times,
                     Moments moments, const m3c2::KalmanParams& params, std::size_t resume_from,
                     const std::optional<Series2D>& prior_mean, const Spread& spread, int threads) {
        m3c2::KalmanBlock b = kalman_block(values, variance, times, resume_from, prior_mean, spread);
        const std::size_t k = std::size_t(params.model), m_ = m3c2::kalman_moments(params.model, params.observation);
        if (prior_mean && prior_mean->shape(1) != k)
          throw m3c2::InvalidArgument("prior_mean must have a column per state");
        if (moments.shape(0) != b.rows || moments.shape(1) != b.epochs || moments.shape(2) != m_)
          throw m3c2::InvalidArgument("moments must be core x epoch x " + std::to_string(m_));
        b.moments = moments.data();
        auto r = run_engine(nb::none(), threads,
                            [&](const m3c2::RunOptions& run) { return m3c2::kalman_smooth(params, b, run); });
        nb::dict d;
        d["mean"] = to_numpy(std::move(r.mean), k);
        d["sd"] = to_numpy(std::move(r.sd), k);
        d["log_likelihood"] = to_numpy(std::move(r.log_likelihood));
        return d;
      },
      "values"_a, "variance"_a.none(), "times"_a, "moments"_a, "params"_a, "resume_from"_a = 0,
      "prior_mean"_a = nb::none(), "spread"_a = nb::none(), "threads"_a = 0);
  m.def(
      "kalman_log_likelihood",
      [kalman_block](const Series2D& values, const std::optional<Series2D>& variance, const Series1D& times,
                     const m3c2::KalmanParams& params, const std::optional<Series2D>& prior_mean, const Spread& spread,
                     int threads) {
        const m3c2::KalmanBlock b = kalman_block(values, variance, times, 0, prior_mean, spread);
        if (prior_mean && prior_mean->shape(1) != std::size_t(params.model))
          throw m3c2::InvalidArgument("prior_mean must have a column per state");
        return run_engine(nb::none(), threads,
                          [&](const m3c2::RunOptions& run) { return m3c2::kalman_log_likelihood(params, b, run); });
      },
      "values"_a, "variance"_a.none(), "times"_a, "params"_a, "prior_mean"_a = nb::none(), "spread"_a = nb::none(),
      "threads"_a = 0);
  m.def(
      "kalman_fit_process_noise",
      [kalman_block](const Series2D& values, const std::optional<Series2D>& variance, const Series1D& times,
                     const m3c2::KalmanParams& params, const Spread& spread, int threads) {
        const m3c2::KalmanBlock b = kalman_block(values, variance, times, 0, std::nullopt, spread);
        const auto fit = run_engine(nb::none(), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::kalman_fit_process_noise(params, b, run);
        });
        return std::make_pair(fit.process_noise, fit.edge);
      },
      "values"_a, "variance"_a.none(), "times"_a, "params"_a, "spread"_a = nb::none(), "threads"_a = 0);
  m.def(
      "lod_observation_variance",
      [](const m3c2::Params& params, const Series1D& lod, const Series1D& sigma1, const Series1D& n1,
         const Series1D& sigma2, const Series1D& n2, int threads) {
        const std::size_t n = lod.shape(0);
        for (const Series1D* a : {&sigma1, &n1, &sigma2, &n2})
          if (a->shape(0) != n) throw m3c2::InvalidArgument("lod, sigma1, n1, sigma2 and n2 must have one length");
        auto out = run_engine(nb::none(), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::lod_observation_variance(params, lod.data(), sigma1.data(), n1.data(), sigma2.data(), n2.data(),
                                                n, run);
        });
        return to_numpy(std::move(out));
      },
      "params"_a, "lod"_a, "sigma1"_a, "n1"_a, "sigma2"_a, "n2"_a, "threads"_a = 0);

  // Time-adaptive M3C2 over a pool of epochs (include/m3c2/tam3c2.hpp). The pool keeps its
  // clouds' arrays alive (the engine views them) and each cloud's index, built once.
  struct Tam3c2Pool {
    std::vector<Points> clouds;
    std::unique_ptr<m3c2::Tam3c2Pool> pool;
  };
  nb::class_<Tam3c2Pool>(m, "Tam3c2Pool")
      .def(
          "__init__",
          [](Tam3c2Pool* self, std::vector<Points> clouds, std::vector<double> times) {
            std::vector<m3c2::PointsView> views;
            for (const Points& c : clouds) views.push_back(view(c));
            new (self) Tam3c2Pool{std::move(clouds), nullptr};
            nb::gil_scoped_release release;
            self->pool = std::make_unique<m3c2::Tam3c2Pool>(std::move(views), std::move(times));
          },
          "clouds"_a, "times"_a)
      .def_prop_ro("size", [](const Tam3c2Pool& p) { return p.pool->size(); });
  // Tam3c2Params, its enums by their option names (tam3c2.hpp's k...Names, their one place).
  nb::class_<m3c2::Tam3c2Params> tam3c2_params(m, "Tam3c2Params");
  tam3c2_params.def(nb::init<>())
      .def_rw("normal_radii", &m3c2::Tam3c2Params::normal_radii)
      .def_rw("window_ratios", &m3c2::Tam3c2Params::window_ratios)
      .def_rw("min_points", &m3c2::Tam3c2Params::min_points)
      .def_rw("cylinder_radius", &m3c2::Tam3c2Params::cylinder_radius)
      .def_rw("max_distance", &m3c2::Tam3c2Params::max_distance)
      .def_rw("sigma_ratio", &m3c2::Tam3c2Params::sigma_ratio)
      .def_rw("space_time_ratio", &m3c2::Tam3c2Params::space_time_ratio)
      .def_rw("registration_error", &m3c2::Tam3c2Params::registration_error)
      .def_rw("confidence", &m3c2::Tam3c2Params::confidence)
      .def_prop_rw(
          "orientation",
          [](const m3c2::Tam3c2Params& p) {
            return std::array<double, 3>{p.orientation[0], p.orientation[1], p.orientation[2]};
          },
          [](m3c2::Tam3c2Params& p, std::array<double, 3> v) { p.orientation = m3c2::Vec3(v[0], v[1], v[2]); })
      .def_prop_rw(
          "break_width", [](const m3c2::Tam3c2Params& p) { return p.change_points.width; },
          [](m3c2::Tam3c2Params& p, std::uint32_t v) { p.change_points.width = v; })
      .def_prop_rw(
          "break_min_size", [](const m3c2::Tam3c2Params& p) { return p.change_points.min_size; },
          [](m3c2::Tam3c2Params& p, std::uint32_t v) { p.change_points.min_size = v; })
      .def_prop_rw(
          "break_jump", [](const m3c2::Tam3c2Params& p) { return p.change_points.jump; },
          [](m3c2::Tam3c2Params& p, std::uint32_t v) { p.change_points.jump = v; })
      .def_prop_rw(
          "break_penalty", [](const m3c2::Tam3c2Params& p) { return p.change_points.penalty; },
          [](m3c2::Tam3c2Params& p, double v) { p.change_points.penalty = v; });
  nb::dict tam3c2_choices;
  const auto enum_field = [&](const char* name, auto field, const auto& names, const char* what) {
    tam3c2_params.def_prop_rw(
        name, [field, &names](const m3c2::Tam3c2Params& p) { return std::string(names[std::size_t(p.*field)]); },
        [field, &names, what](m3c2::Tam3c2Params& p, const std::string& v) {
          std::string known;
          for (std::size_t k = 0; k < names.size(); ++k) {
            if (v == names[k]) return void(p.*field = std::remove_reference_t<decltype(p.*field)>(k));
            known += (k ? ", " : "") + std::string(names[k]);
          }
          throw m3c2::InvalidArgument(std::string("TAM3C2's ") + what + " must be one of " + known + ", got " + v);
        });
    tam3c2_choices[name] = std::vector<std::string>(names.begin(), names.end());
  };
  enum_field("weights", &m3c2::Tam3c2Params::weights, m3c2::kTam3c2WeightsNames, "weights");
  enum_field("lod", &m3c2::Tam3c2Params::lod, m3c2::kTam3c2LodNames, "LOD statistic");
  enum_field("fallback", &m3c2::Tam3c2Params::fallback, m3c2::kTam3c2FallbackNames, "fallback");
  enum_field("breaks", &m3c2::Tam3c2Params::breaks, m3c2::kTam3c2BreaksNames, "window breaks");
  m.attr("TAM3C2_CHOICES") = tam3c2_choices;  // the option names of each enum field, in order
  nb::enum_<m3c2::Tam3c2Source>(m, "Tam3c2Source")
      .value("none", m3c2::Tam3c2Source::kNone)
      .value("windows", m3c2::Tam3c2Source::kWindows)
      .value("epoch", m3c2::Tam3c2Source::kEpoch);
  // epochwise: None, or (5, core, pool) float64: the epochs' own M3C2 distance, lod, significant,
  // n1, n2 (m3c2::Tam3c2Epochwise), NaN where none.
  using Epochwise = nb::ndarray<const double, nb::ndim<3>, nb::c_contig, nb::device::cpu>;
  m.def(
      "tam3c2",
      [](const Tam3c2Pool& pool, const Points& core, std::size_t reference, std::vector<std::size_t> targets,
         const m3c2::Tam3c2Params& p, std::optional<Points> orientations, std::optional<Epochwise> epochwise,
         int threads) {
        if (targets.empty()) throw m3c2::InvalidArgument("TAM3C2 needs at least one target epoch");
        m3c2::Tam3c2Epochwise m;
        if (epochwise) {
          if (epochwise->shape(0) != 5 || epochwise->shape(1) != core.shape(0) ||
              epochwise->shape(2) != pool.pool->size())
            throw m3c2::InvalidArgument("TAM3C2's epochwise M3C2 must be 5 x core points x pool epochs");
          const double* d = epochwise->data();
          const std::size_t plane = core.shape(0) * pool.pool->size();
          m = {d, d + plane, d + 2 * plane, d + 3 * plane, d + 4 * plane};
        }
        auto r = run_engine(nb::none(), threads, [&](const m3c2::RunOptions& run) {
          return m3c2::tam3c2(p, *pool.pool, reference, targets, view(core),
                              orientations ? view(*orientations) : m3c2::PointsView(), m, run);
        });
        const std::size_t nt = targets.size();
        nb::dict d;
        d["normal"] = to_numpy(std::move(r.normal), 3), d["scale"] = to_numpy(std::move(r.scale));
        d["distance"] = to_numpy(std::move(r.distance), nt), d["lod"] = to_numpy(std::move(r.lod), nt);
        d["spread1"] = to_numpy(std::move(r.spread1), nt), d["spread2"] = to_numpy(std::move(r.spread2), nt);
        d["n1"] = to_numpy(std::move(r.n1), nt), d["n2"] = to_numpy(std::move(r.n2), nt);
        d["epochs1"] = to_numpy(std::move(r.epochs1), nt), d["epochs2"] = to_numpy(std::move(r.epochs2), nt);
        d["points1"] = to_numpy(std::move(r.points1), nt), d["points2"] = to_numpy(std::move(r.points2), nt);
        d["significant"] = to_numpy(std::move(r.significant), nt), d["source"] = to_numpy(std::move(r.source), nt);
        return d;
      },
      "pool"_a, "core"_a, "reference"_a, "targets"_a, "params"_a, "orientations"_a = nb::none(),
      "epochwise"_a = nb::none(), "threads"_a = 0);

  m3c2::binding::bind_pbm3c2(m);
}
