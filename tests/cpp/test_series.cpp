// Comparison (series.hpp): each epoch's result equals compute() on the same pair bit for bit,
// for every normal source it accepts and the depth searches and statistics that change the
// per-core-point path; sources that depend on the epoch are refused.

#include <m3c2/series.hpp>

#include "test_support.hpp"

namespace m3c2::test {
namespace {

::testing::AssertionResult SameBits(const Result& a, const Result& b) {
#define M3C2_SAME(field) \
  if (auto r = BitIdentical(a.field, b.field); !r) return r << " in " #field;
  M3C2_SAME(distance)
  M3C2_SAME(lod)
  M3C2_SAME(significant)
  M3C2_SAME(n1)
  M3C2_SAME(n2)
  M3C2_SAME(sigma1)
  M3C2_SAME(sigma2)
  M3C2_SAME(i1)
  M3C2_SAME(i2)
  M3C2_SAME(normal)
  M3C2_SAME(normal_scale)
  M3C2_SAME(roughness)
  M3C2_SAME(status)
#undef M3C2_SAME
  return ::testing::AssertionSuccess();
}

RunOptions with_threads(int n) {
  RunOptions run;
  run.threads = n;
  return run;
}

struct Case {
  const char* name;
  Params params;
};

std::vector<Case> cases() {
  Params base;
  base.normal_diameters = {0.4, 0.8, 1.6};
  base.projection_diameter = 0.5;
  base.max_depth = 1.0;
  std::vector<Case> out{{"multiscale", base}};
  Params median = base;
  median.statistic = Statistic::kMedian;
  median.depth_search = DepthSearch::kProgressive;
  out.push_back({"median progressive", median});
  Params boot = base;
  boot.bootstrap_samples = 30;
  boot.bootstrap_seed = 7;
  boot.normal_subsample_spacing = 0.1;
  out.push_back({"bootstrap subsampled normals", boot});
  Params vertical = base;
  vertical.normal_source = NormalSource::kVertical;
  vertical.normal_diameters.clear();
  out.push_back({"vertical", vertical});
  Params horizontal = base;
  horizontal.normal_source = NormalSource::kHorizontal;
  out.push_back({"horizontal", horizontal});
  Params two_pass = base;
  two_pass.depth_search = DepthSearch::kTwoPass;
  two_pass.first_pass_depth = 0.15;
  out.push_back({"two pass", two_pass});
  return out;
}

/// The points of `cloud` outside the band x0 <= x <= x1.
Cloud without_band(const Cloud& cloud, double x0, double x1) {
  Cloud out;
  for (std::size_t i = 0; i < cloud.size(); ++i)
    if (cloud[i].x() < x0 || cloud[i].x() > x1) out.add(cloud[i]);
  return out;
}

TEST(Series, EveryEpochEqualsComputeBitForBit) {
  const Pair pair = rough_pair(11, 5000);
  for (const Case& c : cases()) {
    const Comparison series(pair.reference.view(), pair.cores.view(), c.params, with_threads(2));
    for (int epoch = 0; epoch < 3; ++epoch) {
      const Cloud compared = rough_pair(100 + epoch, 4000, 10.0, 0.03, 0.04 * epoch).compared;
      const Result a = series.compare(compared.view(), with_threads(3));
      const Result b = compute(pair.reference.view(), compared.view(), pair.cores.view(), c.params, with_threads(1));
      EXPECT_TRUE(SameBits(a, b)) << c.name << ", epoch " << epoch;
    }
  }
}

// The reference's cylinders are searched once for all epochs (series.cpp): every branch of
// project()'s rule must still give compute()'s bits. A hole in the reference (empty reference
// cylinders), one in an epoch (empty compared ones), and an epoch moved beyond the two-pass
// search's first pass (the full depth in both clouds where the reference's short cylinder held
// points); min_points above the smallest cylinders (too few points for the LOD).
TEST(Series, EmptyAndShortCylindersEqualCompute) {
  const Pair pair = rough_pair(15, 5000);
  const Cloud reference = without_band(pair.reference, 2.0, 3.0);
  const Cloud cores = rough_pair(16, 1500).reference;  // over the holes too
  const std::vector<Cloud> epochs{without_band(rough_pair(200, 4000, 10.0, 0.03, 0.0).compared, 6.0, 7.0),
                                  rough_pair(201, 4000, 10.0, 0.03, 0.4).compared};
  for (Case c : cases()) {
    if (c.params.bootstrap_samples > 0) continue;  // searched per epoch: EveryEpochEqualsComputeBitForBit
    c.params.min_points = 4;
    const Comparison series(reference.view(), cores.view(), c.params, with_threads(2));
    std::size_t empty1 = 0, empty2 = 0, too_few = 0;
    for (std::size_t e = 0; e < epochs.size(); ++e) {
      const Result a = series.compare(epochs[e].view(), with_threads(2));
      const Result b = compute(reference.view(), epochs[e].view(), cores.view(), c.params, with_threads(1));
      EXPECT_TRUE(SameBits(a, b)) << c.name << ", epoch " << e;
      for (const PointStatus st : a.status) {
        empty1 += st == PointStatus::kEmptyCylinder1;
        empty2 += st == PointStatus::kEmptyCylinder2;
        too_few += st == PointStatus::kTooFewPointsForLod;
      }
    }
    EXPECT_GT(empty1, 0u) << c.name;
    EXPECT_GT(empty2, 0u) << c.name;
    EXPECT_GT(too_few, 0u) << c.name;
  }
}

TEST(Series, ImposedCoreNormalsEqualCompute) {
  const Pair pair = rough_pair(12, 3000);
  Params p = cases()[0].params;
  p.normal_source = NormalSource::kCorePoints;
  std::vector<double> normals;
  for (std::size_t i = 0; i < pair.cores.size(); ++i) normals.insert(normals.end(), {0.1, -0.2, 1.0 + 0.001 * i});
  normals[0] = normals[1] = normals[2] = 0.0;  // unusable: kDegenerateNormal in both
  const Comparison series(pair.reference.view(), pair.cores.view(), p, {}, normals);
  const Result a = series.compare(pair.compared.view());
  const Result b = compute(pair.reference.view(), pair.compared.view(), pair.cores.view(), p, {}, normals);
  EXPECT_TRUE(SameBits(a, b));
  EXPECT_EQ(a.status[0], PointStatus::kDegenerateNormal);
}

TEST(Series, NormalsAreThoseOfTheFirstEpochsResult) {
  const Pair pair = rough_pair(13, 3000);
  const Comparison series(pair.reference.view(), pair.cores.view(), cases()[0].params);
  const NormalsResult n = series.normals();
  const Result r = series.compare(pair.compared.view());
  EXPECT_TRUE(BitIdentical(n.normal, r.normal));
  EXPECT_TRUE(BitIdentical(n.normal_scale, r.normal_scale));
}

TEST(Series, EpochDependentNormalSourcesAreRefused) {
  const Pair pair = rough_pair(14, 500);
  for (const NormalSource src : {NormalSource::kCompared, NormalSource::kMean}) {
    Params p = cases()[0].params;
    p.normal_source = src;
    EXPECT_THROW(Comparison(pair.reference.view(), pair.cores.view(), p), InvalidArgument);
  }
  const Comparison series(pair.reference.view(), pair.cores.view(), cases()[0].params);
  EXPECT_THROW(series.compare(PointsView(nullptr, 0)), InvalidArgument);
}

}  // namespace
}  // namespace m3c2::test
