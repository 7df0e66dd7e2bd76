"""No function of the binding takes more than 12 parameters (issue 41: a 19-argument TAM3C2
lambda, a 19-argument compute): beyond that a struct or a params object carries them
(Tam3c2Params, UncertaintyArrays), named once. Counts every parameter but self. The package's
Python functions: tests/python/test_layers.py::test_no_function_takes_more_than_12_parameters."""
from __future__ import annotations

import inspect

from m3c2kit import _core

MOST = 12


def _top_level_parameters(signature: str) -> int:
    """The parameters of nanobind's `def name(a: T, b: U[...] = \\0) -> R` text."""
    depth, count, inside = 0, 0, signature[signature.index("(") + 1:]
    for ch in inside:
        if ch in "([":
            depth += 1
        elif ch in ")]":
            if depth == 0:
                break
            depth -= 1
        elif ch == "," and depth == 0:
            count += 1
    return 0 if inside.startswith(")") else count + 1


def _binding_functions():
    objects = [(name, obj) for name, obj in vars(_core).items()]
    for name, obj in list(objects):
        if inspect.isclass(obj):
            objects += [(f"{name}.{k}", v) for k, v in vars(obj).items()]
    for name, obj in objects:
        for overload in getattr(obj, "__nb_signature__", ()) or ():
            text = overload[0]
            count = _top_level_parameters(text)
            if "(self" in text.replace(" ", ""):
                count -= 1
            yield name, count


def test_the_counter_counts():
    assert _top_level_parameters("def f(a: int, b: ndarray[dtype=float64, shape=(*, 3)] = \\0) -> dict") == 2
    assert _top_level_parameters("def f() -> None") == 0
    assert max(n for name, n in _binding_functions() if name == "compute") == 9


def test_no_binding_takes_more_than_twelve_parameters():
    found = list(_binding_functions())
    assert len(found) > 30  # the walk reaches the module's functions and the classes' methods
    over = [(name, n) for name, n in found if n > MOST]
    assert not over, over
