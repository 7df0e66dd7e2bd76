// PB-M3C2's engine functions (include/m3c2/pbm3c2.hpp): a segment table crosses the binding as a
// dict of numpy arrays (one row per segment), so Python can read, filter and pass it back.
#include <m3c2/pbm3c2.hpp>

#include "support.hpp"

#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <algorithm>

namespace m3c2::binding {
namespace {

using namespace nb::literals;

using Labels = nb::ndarray<const std::int64_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using Counts = nb::ndarray<const std::uint64_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using Doubles = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;

nb::dict segments_dict(PlaneSegments&& s) {
  nb::dict d;
  d["label"] = to_numpy(std::move(s.label));
  d["count"] = to_numpy(std::move(s.count));
  d["centroid"] = to_numpy(std::move(s.centroid), 3);
  d["normal"] = to_numpy(std::move(s.normal), 3);
  d["eigenvalues"] = to_numpy(std::move(s.eigenvalues), 3);
  d["major_axis"] = to_numpy(std::move(s.major_axis), 3);
  d["roughness"] = to_numpy(std::move(s.roughness));
  return d;
}

template <class Array, class T>
void copy_column(const nb::dict& d, const char* name, std::size_t per_row, std::size_t rows, std::vector<T>& out) {
  if (!d.contains(name)) throw InvalidArgument(std::string("the segment table has no '") + name + "' column");
  const auto a = nb::cast<Array>(d[name]);
  if (a.size() != per_row * rows)
    throw InvalidArgument(std::string("the segment table's '") + name + "' column must hold " +
                          std::to_string(per_row * rows) + " values, got " + std::to_string(a.size()));
  out.assign(a.data(), a.data() + a.size());
}

PlaneSegments segments_from(const nb::dict& d) {
  PlaneSegments s;
  if (!d.contains("label")) throw InvalidArgument("the segment table has no 'label' column");
  const std::size_t rows = nb::cast<Labels>(d["label"]).size();
  copy_column<Labels>(d, "label", 1, rows, s.label);
  copy_column<Counts>(d, "count", 1, rows, s.count);
  copy_column<Doubles>(d, "centroid", 3, rows, s.centroid);
  copy_column<Doubles>(d, "normal", 3, rows, s.normal);
  copy_column<Doubles>(d, "eigenvalues", 3, rows, s.eigenvalues);
  copy_column<Doubles>(d, "major_axis", 3, rows, s.major_axis);
  copy_column<Doubles>(d, "roughness", 1, rows, s.roughness);
  return s;
}

template <class E>
nb::ndarray<nb::numpy, std::uint8_t> codes(const std::vector<E>& v) {
  std::vector<std::uint8_t> out(v.size());
  std::transform(v.begin(), v.end(), out.begin(), [](E e) { return static_cast<std::uint8_t>(e); });
  return to_numpy(std::move(out));
}

}  // namespace

void bind_pbm3c2(nb::module_& m) {
  nb::class_<PlaneSegmentationParams>(m, "PlaneSegmentationParams")
      .def(nb::init<>())
      .def_rw("normal_diameter", &PlaneSegmentationParams::normal_diameter)
      .def_rw("growth_diameter", &PlaneSegmentationParams::growth_diameter)
      .def_rw("max_angle_degrees", &PlaneSegmentationParams::max_angle_degrees)
      .def_rw("max_plane_distance", &PlaneSegmentationParams::max_plane_distance)
      .def_rw("min_points", &PlaneSegmentationParams::min_points)
      .def_rw("min_normal_points", &PlaneSegmentationParams::min_normal_points);
  nb::class_<CorrespondenceParams>(m, "CorrespondenceParams")
      .def(nb::init<>())
      .def_rw("search_radius", &CorrespondenceParams::search_radius)
      .def_rw("max_angle_degrees", &CorrespondenceParams::max_angle_degrees)
      .def_rw("mutual", &CorrespondenceParams::mutual);
  m.def(
      "segment_planes",
      [](const Points& points, const PlaneSegmentationParams& params, int threads, nb::object progress) {
        PlaneSegmentation s = run_engine(std::move(progress), threads, [&](const RunOptions& run) {
          return segment_planes(view(points), params, run);
        });
        nb::dict d;
        d["labels"] = to_numpy(std::move(s.labels));
        d["status"] = codes(s.status);
        d["segments"] = s.segments;
        return d;
      },
      "points"_a, "params"_a, "threads"_a = 0, "progress"_a = nb::none());
  m.def(
      "plane_segments",
      [](const Points& points, const Labels& labels, const std::vector<double>& direction,
         const std::vector<double>& orientation_points, bool away, int threads) {
        Orientation orientation;
        if (direction.size() != 3) throw InvalidArgument("orientation direction must have 3 components");
        std::copy(direction.begin(), direction.end(), orientation.direction.begin());
        orientation.points = orientation_points, orientation.away = away;
        return segments_dict(run_engine(nb::none(), threads, [&](const RunOptions& run) {
          return plane_segments(view(points), {labels.data(), labels.size()}, orientation, run);
        }));
      },
      "points"_a, "labels"_a, "direction"_a, "orientation_points"_a, "away"_a = false, "threads"_a = 0);
  m.def(
      "nearest_segments",
      [](const nb::dict& reference, const nb::dict& compared, const CorrespondenceParams& params) {
        const SegmentPairs p = nearest_segments(segments_from(reference), segments_from(compared), params);
        nb::dict d;
        d["compared"] = to_numpy(std::vector<std::int64_t>(p.compared));
        d["status"] = codes(p.status);
        return d;
      },
      "reference"_a, "compared"_a, "params"_a);
  m.def(
      "overlapping_segments",
      [](const Points& reference, const Labels& reference_labels, const nb::dict& reference_planes,
         const Points& compared, const Labels& compared_labels, const nb::dict& compared_planes,
         const CorrespondenceParams& params, int threads, nb::object progress) {
        const PlaneSegments ref = segments_from(reference_planes), cmp = segments_from(compared_planes);
        const SegmentPairs p = run_engine(std::move(progress), threads, [&](const RunOptions& run) {
          return overlapping_segments(view(reference), {reference_labels.data(), reference_labels.size()}, ref,
                                      view(compared), {compared_labels.data(), compared_labels.size()}, cmp, params,
                                      run);
        });
        nb::dict d;
        d["compared"] = to_numpy(std::vector<std::int64_t>(p.compared));
        d["status"] = codes(p.status);
        return d;
      },
      "reference"_a, "reference_labels"_a, "reference_planes"_a, "compared"_a, "compared_labels"_a, "compared_planes"_a,
      "params"_a, "threads"_a = 0, "progress"_a = nb::none());
  m.def(
      "compared_plane_misfit",
      [](const Points& reference, const Labels& reference_labels, const nb::dict& reference_planes,
         const Points& compared, const Labels& compared_labels, const nb::dict& compared_planes,
         const Labels& compared_of_reference, int threads) {
        const PlaneSegments ref = segments_from(reference_planes), cmp = segments_from(compared_planes);
        PlaneMisfit m = run_engine(nb::none(), threads, [&](const RunOptions& run) {
          return compared_plane_misfit(view(reference), {reference_labels.data(), reference_labels.size()}, ref,
                                       view(compared), {compared_labels.data(), compared_labels.size()}, cmp,
                                       {compared_of_reference.data(), compared_of_reference.size()}, run);
        });
        nb::dict d;
        d["mean_residual"] = to_numpy(std::move(m.mean_residual));
        d["points"] = to_numpy(std::move(m.points));
        return d;
      },
      "reference"_a, "reference_labels"_a, "reference_planes"_a, "compared"_a, "compared_labels"_a, "compared_planes"_a,
      "compared_of_reference"_a, "threads"_a = 0);
  m.def(
      "segment_candidates",
      [](const nb::dict& reference, const nb::dict& compared, double search_radius) {
        SegmentCandidates c = segment_candidates(segments_from(reference), segments_from(compared), search_radius);
        nb::dict d;
        d["reference"] = to_numpy(std::move(c.reference));
        d["compared"] = to_numpy(std::move(c.compared));
        return d;
      },
      "reference"_a, "compared"_a, "search_radius"_a);
  m.def(
      "pair_features",
      [](const nb::dict& reference, const nb::dict& compared, const Labels& reference_rows,
         const Labels& compared_rows) {
        PairFeatures f =
            pair_features(segments_from(reference), segments_from(compared),
                          {reference_rows.data(), reference_rows.size()}, {compared_rows.data(), compared_rows.size()});
        nb::dict d;
        d["centroid_distance"] = to_numpy(std::move(f.centroid_distance));
        d["normal_angle"] = to_numpy(std::move(f.normal_angle));
        d["roughness_difference"] = to_numpy(std::move(f.roughness_difference));
        return d;
      },
      "reference"_a, "compared"_a, "reference_rows"_a, "compared_rows"_a);
  m.def(
      "plane_changes",
      [](const nb::dict& reference, const nb::dict& compared, const Labels& compared_of_reference,
         const Params& params) {
        PlaneChanges c = plane_changes(segments_from(reference), segments_from(compared),
                                       {compared_of_reference.data(), compared_of_reference.size()}, params);
        nb::dict d;
        d["distance"] = to_numpy(std::move(c.distance));
        d["lod"] = to_numpy(std::move(c.lod));
        d["significant"] = to_numpy(std::move(c.significant));
        d["normal_angle"] = to_numpy(std::move(c.normal_angle));
        return d;
      },
      "reference"_a, "compared"_a, "compared_of_reference"_a, "params"_a);
}

}  // namespace m3c2::binding
