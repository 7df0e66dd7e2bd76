"""Drop-in front ends for users of other M3C2 tools.

- :mod:`m3c2kit.compat.py4dgeo`: py4dgeo's ``Epoch``, ``read_from_xyz``, ``read_from_las`` and
  ``M3C2(...).run()``, so that a py4dgeo script runs by changing its import
  (``import m3c2kit.compat.py4dgeo as py4dgeo``). See docs/python.md for the migration table.
"""
