// PB-M3C2 (include/m3c2/pbm3c2.hpp): facets segmented one to one, their planes exact at projected
// coordinates, pairs by the geometric rule, distances within the noise of a known move and LODs
// that cover it at their nominal rate; the same labels for any thread count; bad inputs refused.

#include <m3c2/errors.hpp>
#include <m3c2/pbm3c2.hpp>

#include "test_support.hpp"

#include <map>

namespace m3c2::test {
namespace {

/// A rectangular facet: centre, unit normal and the half sizes along two in-plane axes.
struct Facet {
  Vec3 centre, normal;
  double half_u, half_v;
};

Vec3 axis_u(const Vec3& n) { return (std::abs(n.z()) < 0.9 ? Vec3::UnitZ() : Vec3::UnitX()).cross(n).normalized(); }

/// `per_facet` points uniform on each facet, noise `sigma` along its normal, each facet shifted
/// by shifts[k] along its normal.
Cloud facets_cloud(const std::vector<Facet>& facets, std::size_t per_facet, double sigma, std::uint64_t seed,
                   const std::vector<double>& shifts = {}) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, sigma);
  Cloud c;
  for (std::size_t k = 0; k < facets.size(); ++k) {
    const Facet& f = facets[k];
    const Vec3 u = axis_u(f.normal), v = f.normal.cross(u);
    const double shift = shifts.empty() ? 0.0 : shifts[k];
    for (std::size_t i = 0; i < per_facet; ++i) {
      // One draw per statement: the order of a call's arguments is unspecified, and GCC and clang
      // differ, which gave the two builds different scenes.
      const double a = unit(rng);
      const double b = unit(rng);
      const double h = noise(rng);
      c.add(f.centre + a * f.half_u * u + b * f.half_v * v + (shift + h) * f.normal);
    }
  }
  return c;
}

/// Facets of a rock face: a row of 2 m squares, tilted alternately, 1 m apart (no two touch).
std::vector<Facet> rock_face(const Vec3& origin = Vec3::Zero()) {
  std::vector<Facet> out;
  for (int k = 0; k < 6; ++k) {
    const double tilt = (k % 2 ? 25.0 : -15.0) * 3.14159265358979323846 / 180.0;
    out.push_back(
        {origin + Vec3(3.0 * k, 0.0, 0.0), Vec3(std::sin(tilt), -std::cos(tilt), 0.3).normalized(), 1.0, 1.0});
  }
  return out;
}

PlaneSegmentationParams segmentation() {
  PlaneSegmentationParams p;
  p.normal_diameter = 0.4;
  p.max_plane_distance = 0.02;
  return p;
}

TEST(PbM3c2, EachFacetIsOneSegment) {
  const Cloud cloud = facets_cloud(rock_face(), 3000, 0.003, 1);
  const PlaneSegmentation s = segment_planes(cloud.view(), segmentation());
  ASSERT_EQ(s.segments, 6u);
  for (std::size_t k = 0; k < 6; ++k) {
    std::map<std::int64_t, int> labels;
    for (std::size_t i = 3000 * k; i < 3000 * (k + 1); ++i) ++labels[s.labels[i]];
    // A facet's points are one segment, apart from a few at its edges whose normals lean.
    int largest = 0;
    for (const auto& [label, count] : labels)
      if (label >= 0) largest = std::max(largest, count);
    EXPECT_GT(largest, 2900) << "facet " << k;
  }
}

TEST(PbM3c2, TheSameLabelsForAnyThreadCount) {
  const Cloud cloud = facets_cloud(rock_face(), 2000, 0.005, 2);
  RunOptions one, many;
  one.threads = 1, many.threads = 4;
  const PlaneSegmentation a = segment_planes(cloud.view(), segmentation(), one);
  const PlaneSegmentation b = segment_planes(cloud.view(), segmentation(), many);
  EXPECT_EQ(a.labels, b.labels);
  const PlaneSegments pa = plane_segments(cloud.view(), a.labels, {}, one);
  const PlaneSegments pb = plane_segments(cloud.view(), b.labels, {}, many);
  EXPECT_EQ(0, std::memcmp(pa.normal.data(), pb.normal.data(), pa.normal.size() * sizeof(double)));
  EXPECT_EQ(0, std::memcmp(pa.roughness.data(), pb.roughness.data(), pa.roughness.size() * sizeof(double)));
}

TEST(PbM3c2, SmallSegmentsAndLonePointsAreUnsegmentedWithAReason) {
  Cloud cloud = facets_cloud(rock_face(), 2000, 0.003, 3);
  cloud.add(100.0, 100.0, 100.0);  // alone: no normal
  PlaneSegmentationParams p = segmentation();
  p.min_points = 2500;  // every facet too small
  const PlaneSegmentation s = segment_planes(cloud.view(), p);
  EXPECT_EQ(s.segments, 0u);
  EXPECT_EQ(s.status.back(), SegmentStatus::kNoNormal);
  EXPECT_EQ(s.status.front(), SegmentStatus::kSmallSegment);
  for (const std::int64_t l : s.labels) EXPECT_EQ(l, -1);
}

TEST(PbM3c2, PlanesAreExactAtProjectedCoordinates) {
  // A facet at UTM-like coordinates: the two-pass moments keep the normal and spread exact.
  const Facet f{Vec3(512345.678, 5412345.678, 812.5), Vec3(0.3, -0.5, 0.8).normalized(), 5.0, 3.0};
  const Cloud cloud = facets_cloud({f}, 20000, 0.004, 4);
  const std::vector<std::int64_t> labels(cloud.size(), 7);
  Orientation up;
  const PlaneSegments s = plane_segments(cloud.view(), labels, up);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s.label[0], 7);
  const Vec3 n(s.normal[0], s.normal[1], s.normal[2]);
  // Oriented up, like f, and within 0.005 degrees: the normal of 20000 points at 4 mm over a
  // 10 x 6 m facet has a standard error of about 0.0006 degrees.
  EXPECT_GT(n.dot(f.normal), std::cos(0.005 * 3.14159265358979323846 / 180.0));
  EXPECT_NEAR(s.roughness[0], 0.004, 0.0001);
  EXPECT_NEAR(s.eigenvalues[0], 25.0 / 3.0, 0.2);  // uniform on [-5, 5]: variance 100 / 12
}

TEST(PbM3c2, KnownMovesAreMeasuredAndTheirLodCoversThem) {
  // Each facet moved along its normal by a known amount; 3000 measurements at 95 % (sd 0.4 %).
  const std::vector<Facet> facets = rock_face(Vec3(600000.0, 5300000.0, 400.0));
  const std::vector<double> shifts = {0.0, 0.01, -0.02, 0.05, 0.003, -0.1};
  Params params;
  params.registration_error = 0.0;
  int covered = 0, measured = 0;
  double worst = 0.0;
  for (std::uint64_t rep = 0; rep < 500; ++rep) {
    const Cloud ref = facets_cloud(facets, 300, 0.01, 10 + 2 * rep);
    const Cloud cmp = facets_cloud(facets, 300, 0.01, 11 + 2 * rep, shifts);
    std::vector<std::int64_t> labels(ref.size());
    for (std::size_t i = 0; i < labels.size(); ++i) labels[i] = std::int64_t(i / 300);
    const PlaneSegments a = plane_segments(ref.view(), labels, {});
    const PlaneSegments b = plane_segments(cmp.view(), labels, {});
    CorrespondenceParams cp;
    cp.search_radius = 1.0;
    const SegmentPairs pairs = nearest_segments(a, b, cp);
    const PlaneChanges c = plane_changes(a, b, pairs.compared, params);
    for (std::size_t k = 0; k < facets.size(); ++k) {
      ASSERT_EQ(pairs.compared[k], std::int64_t(k));
      // The truth along the oriented normal: the facet normals point to -y, oriented +z: same sign.
      const double truth = shifts[k];
      ++measured;
      covered += std::abs(c.distance[k] - truth) <= c.lod[k];
      worst = std::max(worst, std::abs(c.distance[k] - truth));
    }
  }
  EXPECT_LT(worst, 0.004);  // sigma / sqrt(300) * sqrt(2) = 0.8 mm: 5 sd
  const double rate = double(covered) / measured;
  EXPECT_GT(rate, 0.935) << covered << " of " << measured;
  EXPECT_LT(rate, 0.965) << covered << " of " << measured;
}

TEST(PbM3c2, LodWidensWithTheLeverOfATiltedComparedPlane) {
  // The compared segment covers only half of the reference facet: its plane is met far from its
  // centroid, where its tilt's error adds to its offset's.
  const Facet f{Vec3::Zero(), Vec3::UnitZ(), 2.0, 2.0};
  const Cloud ref = facets_cloud({f}, 400, 0.01, 5);
  Cloud half;
  const Cloud full = facets_cloud({f}, 800, 0.01, 6);
  for (std::size_t i = 0; i < full.size(); ++i)
    if (full[i].x() > 0.0) half.add(full[i]);
  const PlaneSegments a = plane_segments(ref.view(), std::vector<std::int64_t>(ref.size(), 0), {});
  const PlaneSegments b = plane_segments(half.view(), std::vector<std::int64_t>(half.size(), 0), {});
  Params params;
  const std::vector<std::int64_t> pair = {0};
  const PlaneChanges c = plane_changes(a, b, pair, params);
  const double centroid_only = 1.959963984540054 * std::sqrt(a.roughness[0] * a.roughness[0] / double(a.count[0]) +
                                                             b.roughness[0] * b.roughness[0] / double(b.count[0]));
  EXPECT_GT(c.lod[0], 1.2 * centroid_only);
}

TEST(PbM3c2, NearestSegmentsGatesAndMutual) {
  // Reference: facets 0 and 1; compared: one facet near both, and one tilted 60 degrees.
  const std::vector<Facet> ref = {{Vec3(0, 0, 0), Vec3::UnitZ(), 1, 1}, {Vec3(0.5, 0, 0.4), Vec3::UnitZ(), 1, 1}};
  const std::vector<Facet> cmp = {{Vec3(0.4, 0, 0.35), Vec3::UnitZ(), 1, 1},
                                  {Vec3(0, 0, 0.1), Vec3(0, std::sin(1.0472), std::cos(1.0472)), 1, 1}};
  const Cloud a = facets_cloud(ref, 200, 0.001, 7), b = facets_cloud(cmp, 200, 0.001, 8);
  std::vector<std::int64_t> labels(400);
  for (std::size_t i = 0; i < 400; ++i) labels[i] = std::int64_t(i / 200);
  const PlaneSegments sa = plane_segments(a.view(), labels, {}), sb = plane_segments(b.view(), labels, {});
  CorrespondenceParams p;
  p.search_radius = 2.0;
  SegmentPairs pairs = nearest_segments(sa, sb, p);
  EXPECT_EQ(pairs.compared, (std::vector<std::int64_t>{0, 0}));  // the tilted one is gated out
  p.mutual = true;
  pairs = nearest_segments(sa, sb, p);
  EXPECT_EQ(pairs.compared, (std::vector<std::int64_t>{-1, 0}));
  EXPECT_EQ(pairs.status[0], PairStatus::kNotMutual);
  p.mutual = false, p.max_angle_degrees = 90.0, p.search_radius = 0.2;
  pairs = nearest_segments(sa, sb, p);
  EXPECT_EQ(pairs.compared, (std::vector<std::int64_t>{1, 0}));  // no gate: the tilted one is nearest 0
  p.search_radius = 0.05;
  pairs = nearest_segments(sa, sb, p);
  EXPECT_EQ(pairs.status[0], PairStatus::kNoCandidate);
  const SegmentCandidates cand = segment_candidates(sa, sb, 2.0);
  EXPECT_EQ(cand.reference, (std::vector<std::int64_t>{0, 0, 1, 1}));
  EXPECT_EQ(cand.compared, (std::vector<std::int64_t>{0, 1, 0, 1}));
  const PairFeatures f = pair_features(sa, sb, cand.reference, cand.compared);
  EXPECT_NEAR(f.normal_angle[1], 1.0472, 0.01);
  const Vec3 c1(sa.centroid[0], sa.centroid[1], sa.centroid[2]), c2(sb.centroid[0], sb.centroid[1], sb.centroid[2]);
  EXPECT_DOUBLE_EQ(f.centroid_distance[0], (c2 - c1).norm());
  EXPECT_DOUBLE_EQ(f.roughness_difference[0], std::abs(sa.roughness[0] - sb.roughness[0]));
  EXPECT_THROW(pair_features(sa, sb, std::vector<std::int64_t>{2}, std::vector<std::int64_t>{0}), InvalidArgument);
}

/// A segment table of `n` random planes (centroids in a 10 m cube, random normals).
PlaneSegments random_planes(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 10.0);
  std::normal_distribution<double> g(0.0, 1.0);
  PlaneSegments s;
  for (std::size_t i = 0; i < n; ++i) {
    Vec3 normal;
    for (int a = 0; a < 3; ++a) normal(a) = g(rng);  // one draw per statement (argument order)
    normal.normalize();
    s.label.push_back(std::int64_t(i));
    s.count.push_back(100);
    for (int a = 0; a < 3; ++a) s.centroid.push_back(u(rng)), s.normal.push_back(normal(a));
    for (int a = 0; a < 3; ++a) s.eigenvalues.push_back(1.0), s.major_axis.push_back(0.0);
    s.roughness.push_back(0.01);
  }
  return s;
}

TEST(PbM3c2, NearestSegmentsIsTheBruteForceNearest) {
  // The growing balls against every pair scanned: the same pair, ties to the lower row.
  for (std::uint64_t seed = 0; seed < 20; ++seed) {
    const PlaneSegments a = random_planes(300, 2 * seed), b = random_planes(300, 2 * seed + 1);
    CorrespondenceParams p;
    p.search_radius = 0.3 + 0.5 * double(seed % 5);
    p.max_angle_degrees = 20.0 + 3.0 * double(seed);
    const double min_cosine = std::cos(p.max_angle_degrees * 3.14159265358979323846 / 180.0);
    const SegmentPairs pairs = nearest_segments(a, b, p);
    for (std::size_t i = 0; i < a.size(); ++i) {
      std::int64_t best = -1;
      double best2 = p.search_radius * p.search_radius;
      for (std::size_t j = 0; j < b.size(); ++j) {
        const Vec3 d(b.centroid[3 * j] - a.centroid[3 * i], b.centroid[3 * j + 1] - a.centroid[3 * i + 1],
                     b.centroid[3 * j + 2] - a.centroid[3 * i + 2]);
        double cosine = 0.0;
        for (int k = 0; k < 3; ++k) cosine += a.normal[3 * i + k] * b.normal[3 * j + k];
        if (std::abs(cosine) < min_cosine || d.squaredNorm() > best2 || (best >= 0 && d.squaredNorm() == best2))
          continue;
        best2 = d.squaredNorm(), best = std::int64_t(j);
      }
      ASSERT_EQ(pairs.compared[i], best) << "seed " << seed << " row " << i;
    }
  }
}

TEST(PbM3c2, OverlapPairsAPartlyCoveredSurfaceWhereCentroidsDrift) {
  // Reference: a 4 m facet. Compared: its right half only (its centroid 1 m away), moved 2 cm along
  // the normal, and a small parallel ledge 0.3 m above, 0.4 m left of the centre: the nearest
  // centroid is the ledge's, the overlap is the facet's.
  const Cloud ref = facets_cloud({{Vec3::Zero(), Vec3::UnitZ(), 2.0, 2.0}}, 4000, 0.002, 21);
  Cloud cmp;
  const Cloud full = facets_cloud({{Vec3(0, 0, 0.02), Vec3::UnitZ(), 2.0, 2.0}}, 4000, 0.002, 22);
  for (std::size_t i = 0; i < full.size(); ++i)
    if (full[i].x() > 0.0) cmp.add(full[i]);
  const std::size_t half = cmp.size();
  cmp.append(facets_cloud({{Vec3(-0.4, 0, 0.3), Vec3::UnitZ(), 0.25, 0.25}}, 200, 0.002, 23));
  std::vector<std::int64_t> ref_labels(ref.size(), 0), cmp_labels(cmp.size(), 5);
  for (std::size_t i = half; i < cmp.size(); ++i) cmp_labels[i] = 9;
  const PlaneSegments a = plane_segments(ref.view(), ref_labels, {});
  const PlaneSegments b = plane_segments(cmp.view(), cmp_labels, {});
  CorrespondenceParams p;
  p.search_radius = 1.0;
  EXPECT_EQ(nearest_segments(a, b, p).compared, (std::vector<std::int64_t>{1}));  // the ledge
  const SegmentPairs overlap = overlapping_segments(ref.view(), ref_labels, a, cmp.view(), cmp_labels, b, p);
  EXPECT_EQ(overlap.compared, (std::vector<std::int64_t>{0}));  // the facet
  p.mutual = true;
  EXPECT_EQ(overlapping_segments(ref.view(), ref_labels, a, cmp.view(), cmp_labels, b, p).compared,
            (std::vector<std::int64_t>{0}));
  const PlaneChanges c = plane_changes(a, b, overlap.compared, Params{});
  EXPECT_NEAR(c.distance[0], 0.02, 0.001);
  // Nothing within reach: no candidate; a label without a row in its planes: refused.
  p.mutual = false, p.search_radius = 0.001;
  const SegmentPairs none = overlapping_segments(ref.view(), ref_labels, a, cmp.view(), cmp_labels, b, p);
  EXPECT_EQ(none.status[0], PairStatus::kNoCandidate);
  std::vector<std::int64_t> stray = cmp_labels;
  stray[0] = 77;
  EXPECT_THROW(overlapping_segments(ref.view(), ref_labels, a, cmp.view(), stray, b, p), InvalidArgument);
}

/// The points of `c` with x > `edge`.
Cloud beyond(const Cloud& c, double edge = 0.0) {
  Cloud out;
  for (std::size_t i = 0; i < c.size(); ++i)
    if (c[i].x() > edge) out.add(c[i]);
  return out;
}

/// m3c2kit.pbm3c2's rule (analysis/pbm3c2.py, _refuse_misfits): the pair of reference row `i` is refused
/// when |misfit| exceeds its LOD by more than 3 of the misfit's standard errors sigma2 / sqrt(k).
bool refused_as_misfit(const PlaneMisfit& m, const PlaneSegments& compared, std::int64_t j, double lod,
                       std::size_t i = 0) {
  return std::abs(m.mean_residual[i]) - 3.0 * compared.roughness[std::size_t(j)] / std::sqrt(double(m.points[i])) > lod;
}

TEST(PbM3c2, APartlyCoveredTruePlaneIsRefusedNoMoreThanTheRuleAllows) {
  // The misfit is the mean residual of the compared points over the reference segment's footprint,
  // chosen by their place in the plane, not by their residuals: for a true plane its spread is at
  // most sigma2 / sqrt(k), and 3 of those beyond the LOD refuse at most 0.27 % of true planes. Two
  // halves: the compared epoch sees half of the reference facet (then every compared point is over
  // it), and the reference sees half of the compared facet (half of its points are). Before, the
  // reference points' feet beyond the compared edge all found the same edge points: counted per
  // foot, 11 % of the first kind were refused; counted once each, still 1-2 of 10.
  const Facet ref_facet{Vec3::Zero(), Vec3::UnitZ(), 2.0, 2.0}, cmp_facet{Vec3(0, 0, 0.02), Vec3::UnitZ(), 2.0, 2.0};
  constexpr int kDraws = 200;  // of each kind
  int refused = 0, measured = 0;
  double z2 = 0.0;  // the misfits in their standard errors, squared
  for (std::uint64_t seed = 0; seed < kDraws; ++seed) {
    const Cloud ref_all = facets_cloud({ref_facet}, 4000, 0.002, 5000 + 2 * seed);
    const Cloud cmp_all = facets_cloud({cmp_facet}, 4000, 0.002, 5001 + 2 * seed);
    for (const bool compared_half : {true, false}) {
      const Cloud ref = compared_half ? ref_all : beyond(ref_all), cmp = compared_half ? beyond(cmp_all) : cmp_all;
      const std::vector<std::int64_t> ref_labels(ref.size(), 0), cmp_labels(cmp.size(), 0), pair = {0};
      const PlaneSegments a = plane_segments(ref.view(), ref_labels, {});
      const PlaneSegments b = plane_segments(cmp.view(), cmp_labels, {});
      const PlaneMisfit m = compared_plane_misfit(ref.view(), ref_labels, a, cmp.view(), cmp_labels, b, pair);
      // Over the footprint: every compared point over the reference facet, none 3 spacings beyond it.
      std::size_t inside = 0, near = 0;
      const double reach = 3.0 * std::sqrt(16.0 / double(ref.size()) * (compared_half ? 1.0 : 0.5));
      for (std::size_t k = 0; k < cmp.size(); ++k) {
        inside += compared_half || cmp[k].x() > 0.0;
        near += compared_half || cmp[k].x() > -reach;
      }
      EXPECT_GE(m.points[0], inside - inside / 1000) << "seed " << seed;
      EXPECT_LE(m.points[0], near) << "seed " << seed;
      const double lod = plane_changes(a, b, pair, Params{}).lod[0];
      refused += refused_as_misfit(m, b, 0, lod);
      const double z = m.mean_residual[0] / (b.roughness[0] / std::sqrt(double(m.points[0])));
      z2 += z * z, ++measured;
    }
  }
  // Binomial(400, 0.0027): 1.1 expected, 5 or more 0.5 % of the time. The spread itself: at most 1
  // standard error (a subset of a least-squares fit's residuals spreads less), over 400 draws.
  EXPECT_LE(refused, 4);
  EXPECT_LT(std::sqrt(z2 / measured), 1.0) << refused << " refused";
}

TEST(PbM3c2, AComparedPlaneOverAStepMisfitsItsPoints) {
  // Reference: a 2 m facet at x < 0. Compared: the same facet moved 1 cm, labelled together with a
  // second level 0.5 m higher at x > 0 (a step grown into one segment): its plane is tilted and off
  // the facet's points by decimetres; the facet alone is off them by its noise only. The upper
  // level is not over the reference facet, however near its edge: counted wherever its nearest
  // reference point was in the facet (within 1 m), its points within 0.86 m of the edge pulled the
  // misfit from 48 mm down to 8 mm, and the step was kept.
  const Cloud ref = facets_cloud({{Vec3(-1, 0, 0), Vec3::UnitZ(), 1.0, 1.0}}, 2000, 0.003, 31);
  Cloud cmp = facets_cloud({{Vec3(-1, 0, 0.01), Vec3::UnitZ(), 1.0, 1.0}}, 2000, 0.003, 32);
  const std::size_t lower = cmp.size();
  cmp.append(facets_cloud({{Vec3(1, 0, 0.5), Vec3::UnitZ(), 1.0, 1.0}}, 2000, 0.003, 33));
  const std::vector<std::int64_t> ref_labels(ref.size(), 0);
  std::vector<std::int64_t> merged(cmp.size(), 0), apart(cmp.size(), 0);
  for (std::size_t i = lower; i < cmp.size(); ++i) apart[i] = 1;
  const PlaneSegments a = plane_segments(ref.view(), ref_labels, {});
  const std::vector<std::int64_t> pair = {0};
  const PlaneSegments step = plane_segments(cmp.view(), merged, {});
  const PlaneMisfit off = compared_plane_misfit(ref.view(), ref_labels, a, cmp.view(), merged, step, pair);
  EXPECT_GT(std::abs(off.mean_residual[0]), 0.04);
  // The lower level, and of the upper one only what lies within 3 spacings (3 x 4.5 cm) of the edge.
  std::size_t near_edge = 0;
  for (std::size_t i = lower; i < cmp.size(); ++i) near_edge += cmp[i].x() < 0.135;
  EXPECT_GE(off.points[0], lower - 2);
  EXPECT_LE(off.points[0], lower + near_edge);
  EXPECT_TRUE(refused_as_misfit(off, step, 0, plane_changes(a, step, pair, Params{}).lod[0]));
  const PlaneSegments facets = plane_segments(cmp.view(), apart, {});
  const PlaneMisfit fits = compared_plane_misfit(ref.view(), ref_labels, a, cmp.view(), apart, facets, pair);
  // The mean of ~2000 residuals of sd 3 mm: 0.07 mm; 5 sd (all of them: exactly 0 but rounding).
  EXPECT_LT(std::abs(fits.mean_residual[0]), 0.0004);
  EXPECT_FALSE(refused_as_misfit(fits, facets, 0, plane_changes(a, facets, pair, Params{}).lod[0]));
  RunOptions one, many;
  one.threads = 1, many.threads = 4;
  EXPECT_EQ(compared_plane_misfit(ref.view(), ref_labels, a, cmp.view(), apart, facets, pair, one).mean_residual,
            compared_plane_misfit(ref.view(), ref_labels, a, cmp.view(), apart, facets, pair, many).mean_residual);
  const PlaneMisfit none =
      compared_plane_misfit(ref.view(), ref_labels, a, cmp.view(), apart, facets, std::vector<std::int64_t>{-1});
  EXPECT_TRUE(std::isnan(none.mean_residual[0]));
  EXPECT_EQ(none.points[0], 0u);
}

TEST(PbM3c2, AComparedSegmentPairedWithSeveralReferenceSegmentsCountsForEach) {
  // Reference: two 2 m facets 0.2 m apart, each its own segment. Compared: the left one moved 1 cm and
  // the right one raised 0.5 m, grown into one segment, which both reference segments are paired
  // with. Each counts the compared points over its own footprint, once (the gap is wider than the
  // two reaches), and the step shows on both sides, with opposite signs. The same numbers as each
  // pair alone, bit for bit, whatever the thread count.
  Cloud ref = facets_cloud({{Vec3(-1, 0, 0), Vec3::UnitZ(), 1.0, 1.0}}, 2000, 0.003, 41);
  ref.append(facets_cloud({{Vec3(1.2, 0, 0), Vec3::UnitZ(), 1.0, 1.0}}, 2000, 0.003, 42));
  Cloud cmp = facets_cloud({{Vec3(-1, 0, 0.01), Vec3::UnitZ(), 1.0, 1.0}}, 2000, 0.003, 43);
  cmp.append(facets_cloud({{Vec3(1.2, 0, 0.5), Vec3::UnitZ(), 1.0, 1.0}}, 2000, 0.003, 44));
  std::vector<std::int64_t> ref_labels(ref.size(), 3);
  for (std::size_t i = 2000; i < ref.size(); ++i) ref_labels[i] = 8;
  const std::vector<std::int64_t> cmp_labels(cmp.size(), 5);
  const PlaneSegments a = plane_segments(ref.view(), ref_labels, {});
  const PlaneSegments b = plane_segments(cmp.view(), cmp_labels, {});
  const std::vector<std::int64_t> both = {0, 0};
  RunOptions one, many;
  one.threads = 1, many.threads = 4;
  const PlaneMisfit m = compared_plane_misfit(ref.view(), ref_labels, a, cmp.view(), cmp_labels, b, both, many);
  EXPECT_LT(m.mean_residual[0], -0.04);
  EXPECT_GT(m.mean_residual[1], 0.04);
  EXPECT_GE(m.points[0], 1998u);
  EXPECT_GE(m.points[1], 1998u);
  EXPECT_LE(m.points[0] + m.points[1], cmp.size());
  const PlaneMisfit left = compared_plane_misfit(ref.view(), ref_labels, a, cmp.view(), cmp_labels, b,
                                                 std::vector<std::int64_t>{0, -1}, one);
  const PlaneMisfit right = compared_plane_misfit(ref.view(), ref_labels, a, cmp.view(), cmp_labels, b,
                                                  std::vector<std::int64_t>{-1, 0}, one);
  EXPECT_EQ(m.mean_residual, (std::vector<double>{left.mean_residual[0], right.mean_residual[1]}));
  EXPECT_EQ(m.points, (std::vector<std::uint64_t>{left.points[0], right.points[1]}));
  EXPECT_EQ(m.mean_residual,
            compared_plane_misfit(ref.view(), ref_labels, a, cmp.view(), cmp_labels, b, both, one).mean_residual);
  // The right facet's points in no segment: the compared points over them count for no segment, and
  // the left segment's misfit is unchanged.
  std::vector<std::int64_t> left_only = ref_labels;
  for (std::size_t i = 2000; i < ref.size(); ++i) left_only[i] = -1;
  const PlaneSegments a_left = plane_segments(ref.view(), left_only, {});
  const PlaneMisfit alone =
      compared_plane_misfit(ref.view(), left_only, a_left, cmp.view(), cmp_labels, b, std::vector<std::int64_t>{0});
  EXPECT_EQ(alone.mean_residual[0], left.mean_residual[0]);
  EXPECT_EQ(alone.points[0], left.points[0]);
}

TEST(PbM3c2, BadInputsAreRefused) {
  const Cloud cloud = facets_cloud(rock_face(), 100, 0.003, 9);
  PlaneSegmentationParams p = segmentation();
  p.normal_diameter = 0.0;
  EXPECT_THROW(segment_planes(cloud.view(), p), InvalidArgument);
  p = segmentation(), p.max_angle_degrees = 95.0;
  EXPECT_THROW(segment_planes(cloud.view(), p), InvalidArgument);
  p = segmentation(), p.min_normal_points = 2;
  EXPECT_THROW(segment_planes(cloud.view(), p), InvalidArgument);
  EXPECT_THROW(plane_segments(cloud.view(), std::vector<std::int64_t>(3, 0), {}), InvalidArgument);
  Cloud bad = cloud;
  bad.xyz[4] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(plane_segments(bad.view(), std::vector<std::int64_t>(bad.size(), 0), {}), InvalidArgument);
  EXPECT_THROW(segment_planes(bad.view(), segmentation()), InvalidArgument);
  const PlaneSegments s = plane_segments(cloud.view(), std::vector<std::int64_t>(cloud.size(), 0), {});
  CorrespondenceParams cp;
  EXPECT_THROW(nearest_segments(s, s, cp), InvalidArgument);  // search_radius 0
  Params params;
  params.lod = Lod::kBootstrap;
  EXPECT_THROW(plane_changes(s, s, std::vector<std::int64_t>{0}, params), InvalidArgument);
  EXPECT_THROW(plane_changes(s, s, std::vector<std::int64_t>{0, 0}, Params{}), InvalidArgument);
  const std::vector<std::int64_t> labels(cloud.size(), 0);
  EXPECT_THROW(compared_plane_misfit(cloud.view(), labels, s, cloud.view(), labels, s, std::vector<std::int64_t>{1}),
               InvalidArgument);  // a compared row out of range
  EXPECT_THROW(compared_plane_misfit(cloud.view(), labels, s, cloud.view(), labels, s, std::vector<std::int64_t>{}),
               InvalidArgument);  // not one per reference row
  EXPECT_THROW(compared_plane_misfit(cloud.view(), std::vector<std::int64_t>(3, 0), s, cloud.view(), labels, s,
                                     std::vector<std::int64_t>{0}),
               InvalidArgument);  // not one label per point
}

}  // namespace
}  // namespace m3c2::test
