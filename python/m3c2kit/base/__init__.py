"""The bottom layer (docs/architecture.md): the package's exceptions and warning, its optional
imports, progress over a run's phases, and the testing aid that signals a run at a phase."""
