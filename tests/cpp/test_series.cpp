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
