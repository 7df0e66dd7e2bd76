#pragma once
// What every binding file shares: the array types it takes (viewed, not copied), numpy arrays out
// of the engine's vectors (not copied), and the engine run with the GIL released and Python's
// progress callback and Ctrl-C bridged to it.

#include <m3c2/errors.hpp>
#include <m3c2/points_view.hpp>
#include <m3c2/result.hpp>
#include <m3c2/run_options.hpp>

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

namespace m3c2::binding {

namespace nb = nanobind;

using Points = nb::ndarray<const double, nb::shape<-1, 3>, nb::c_contig, nb::device::cpu>;

inline m3c2::PointsView view(const Points& a) { return {a.data(), a.shape(0)}; }

using Ids = nb::ndarray<const std::uint32_t, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
using Table = nb::ndarray<const double, nb::shape<-1, 8>, nb::c_contig, nb::device::cpu>;
using Flat = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using Values = nb::ndarray<const double, nb::ndim<1>, nb::c_contig, nb::device::cpu>;

template <class T>
nb::ndarray<nb::numpy, T> to_numpy(std::vector<T>&& values, std::size_t columns = 1) {
  auto* owned = new std::vector<T>(std::move(values));
  nb::capsule owner(owned, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
  const std::size_t rows = owned->size() / columns;
  if (columns == 1) return nb::ndarray<nb::numpy, T>(owned->data(), {rows}, owner);
  return nb::ndarray<nb::numpy, T>(owned->data(), {rows, columns}, owner);
}

inline nb::ndarray<nb::numpy, std::uint8_t> status_array(const std::vector<m3c2::PointStatus>& s) {
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

}  // namespace m3c2::binding
