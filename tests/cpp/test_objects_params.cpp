// The checks of 4D-OBC's parameters (src/series/objects_by_change.cpp): each refusal names the
// ObjectsParams field, the engine's own term, never a command-line flag (the Python layer shows
// the message and maps the field to its option).

#include <m3c2/errors.hpp>
#include <m3c2/objects_by_change.hpp>

#include <gtest/gtest.h>

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace m3c2::test {
namespace {

constexpr std::size_t kEpochs = 30;  // longer than the default change-point window (24)

/// The InvalidArgument's text find_seeds() gives for `p`, or "" when it takes them.
std::string refusal(const ObjectsParams& p) {
  const std::vector<double> distances(kEpochs, 0.0);  // one core point
  try {
    find_seeds(distances.data(), 1, kEpochs, p);
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "";
}

struct BadField {
  const char* field;
  std::function<void(ObjectsParams&)> spoil;
};

TEST(ObjectsParams, RefusalsNameTheFieldNotAFlag) {
  const std::vector<BadField> cases = {
      {"min_period", [](ObjectsParams& p) { p.min_period = 0; }},
      {"seed_subsampling", [](ObjectsParams& p) { p.seed_subsampling = 0; }},
      {"neighbourhood_radius", [](ObjectsParams& p) { p.neighbourhood_radius = 0.0; }},
      {"thresholds", [](ObjectsParams& p) { p.thresholds.clear(); }},
      {"thresholds",
       [](ObjectsParams& p) {
         p.thresholds = {0.5, 1.5};
       }},
  };
  EXPECT_EQ(refusal(ObjectsParams{}), "");
  for (const BadField& c : cases) {
    ObjectsParams p;
    c.spoil(p);
    const std::string message = refusal(p);
    EXPECT_EQ(message.rfind(c.field, 0), 0u) << message;
    EXPECT_EQ(message.find("--"), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace m3c2::test
