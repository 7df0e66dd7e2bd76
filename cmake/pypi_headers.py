"""Prints where the PyPI build requirements put their headers (cmake/m3c2_dependencies.cmake):
line 1, the prefix of cmeel-eigen (Eigen's CMake config under share/eigen3/cmake); line 2, the
include directory of boost-headers (boost/math/...). An empty line where a package is absent."""
import os
import sys


def cmeel_prefix():
    # cmeel packages install into <site-packages>/cmeel.prefix, a directory that is no module.
    for entry in sys.path:
        prefix = os.path.join(entry or os.curdir, "cmeel.prefix")
        if os.path.isfile(os.path.join(prefix, "share", "eigen3", "cmake", "Eigen3Config.cmake")):
            return os.path.abspath(prefix)
    return ""


def boost_include():
    try:
        import boost_headers
    except ImportError:
        return ""
    include = str(boost_headers.get_include())
    return include if os.path.isfile(os.path.join(include, "boost", "math", "distributions", "students_t.hpp")) else ""


print(cmeel_prefix())
print(boost_include())
