"""The package's layers depend one way (docs/architecture.md):
base <- io <- engine <- settings <- run <- output <- features <- api <- cli. A module's layer is
the folder it is in (m3c2kit/<folder>/...), so moving a file is the only way to change it. Each
module may import only modules of its own layer or of the layers to its left; nothing imports
the command line. Read from the source with ast (every import, including those inside
functions)."""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "python" / "m3c2kit"
ORDER = ("base", "io", "engine", "settings", "run", "output", "features", "api", "cli")

#: The layer of each folder of m3c2kit; the features are four folders of one layer.
FOLDERS = {"base": "base", "io": "io", "engine": "engine", "settings": "settings", "run": "run", "output": "output",
           "analysis": "features", "classify": "features", "series": "features", "compat": "features", "cli": "cli"}
#: The package's root holds only its face: the public API (api.py), the re-exports (__init__,
#: exempt) and `python -m m3c2kit`; _core is the binding, which the engine imports.
ROOT_MODULES = {"api": "api", "__main__": "cli", "_core": "engine"}


def layer_of(module: str) -> str:
    head = module.split(".")[0]
    if "." not in module and head in ROOT_MODULES:
        return ROOT_MODULES[head]
    if head in FOLDERS:
        return FOLDERS[head]
    raise AssertionError(f"m3c2kit.{module} is in no layer's folder: move it into one of {sorted(FOLDERS)} "
                         f"(docs/architecture.md)")


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


def test_every_module_is_in_a_layer_folder():
    modules = sorted(_name(p) for p in PACKAGE.rglob("*.py") if _name(p))
    assert [m for m in modules if m.split(".")[0] not in FOLDERS and m not in ROOT_MODULES] == []
    assert set(FOLDERS) <= {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}


def test_no_function_takes_more_than_12_parameters():
    """Small named types instead of long signatures (issue 32); compat/ mirrors py4dgeo's own."""
    long = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.relative_to(PACKAGE).parts[0] == "compat":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                a = node.args
                n = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + (a.vararg is not None) + (a.kwarg is not None)
                if n > 12:
                    long.append(f"m3c2kit.{_name(path)}.{node.name}: {n}")
    assert long == []
