"""The package's layers depend one way (docs/architecture.md):
errors <- io <- engine <- settings <- run <- report <- cli. Each module may import only modules of
its own layer or of the layers to its left; nothing imports the command line. Read from the
source with ast (every import, including those inside functions)."""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "python" / "m3c2kit"
ORDER = ("errors", "io", "engine", "settings", "run", "report", "cli")

#: Layer of each module (dotted names below m3c2kit); a package stands for its modules.
LAYERS = {
    "errors": "errors", "optional": "errors", "fault_hook": "errors", "io": "io",
    "_core": "engine", "engine": "engine", "result": "engine",
    "settings": "settings", "limits": "settings",
    "run": "run", "api": "run", "tiling": "run", "raster": "run", "diagnostics": "run", "uncertainty_inputs": "run",
    "analysis": "run", "compat": "run", "classify": "run", "lod_rates": "run", "lod_table": "run", "quality": "run", "phases": "run",
    "report": "report", "summary": "report", "writing": "report",
    "cli": "cli", "cli_parser": "cli", "cli_integers": "cli", "analysis.cli": "cli", "classify.cli": "cli", "series": "run", "series.report": "report", "series.cli": "cli", "__main__": "cli",
}


def layer_of(module: str) -> str:
    parts = module.split(".")
    for n in range(len(parts), 0, -1):
        if ".".join(parts[:n]) in LAYERS:
            return LAYERS[".".join(parts[:n])]
    raise AssertionError(f"m3c2kit.{module} has no layer in tests/python/test_layers.py (add it, and to "
                         f"docs/architecture.md)")


def _name(path: Path) -> str:
    rel = path.relative_to(PACKAGE).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def _is_module(dotted: str) -> bool:
    base = PACKAGE.joinpath(*dotted.split("."))
    return base.with_suffix(".py").exists() or (base / "__init__.py").exists()


def imports(path: Path) -> set[str]:
    """Modules of m3c2kit that `path` imports (relative or absolute)."""
    here = _name(path).split(".") if _name(path) else []
    package = here if path.name == "__init__.py" else here[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name[len("m3c2kit."):] for a in node.names if a.name.startswith("m3c2kit.")}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = ".".join(package[: len(package) - node.level + 1])
                target = ".".join(x for x in (base, node.module or "") if x)
            elif node.module and node.module.split(".")[0] == "m3c2kit":
                target = node.module[len("m3c2kit"):].lstrip(".")
            else:
                continue
            if target:
                found.add(target)
            for alias in node.names:
                candidate = f"{target}.{alias.name}" if target else alias.name
                if _is_module(candidate) or candidate == "_core":
                    found.add(candidate)
    return found


def test_every_import_goes_to_the_same_or_a_lower_layer():
    wrong = []
    for path in sorted(PACKAGE.rglob("*.py")):
        name = _name(path)
        if not name:
            continue  # the package's root re-exports the public API from every layer
        own = ORDER.index(layer_of(name))
        for target in sorted(imports(path)):
            if ORDER.index(layer_of(target)) > own:
                wrong.append(f"m3c2kit.{name} ({layer_of(name)}) imports m3c2kit.{target} ({layer_of(target)})")
    assert wrong == []


def test_nothing_imports_the_command_line():
    importers = sorted(_name(p) for p in PACKAGE.rglob("*.py") if "cli" in imports(p) and _name(p) != "__main__")
    assert importers == []
