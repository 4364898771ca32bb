"""The Python package's layers import only downwards, and no modules
import each other in a circle, as tests/layers.rs checks for the Rust
core: read from the sources (every import, at module level or inside a
function, under TYPE_CHECKING too), so an import that breaks the order
fails here, naming the file, the line and the import.

A unit is a top-level module or a subpackage of ``pupper_core``; each
sits on a layer, and a unit may import only units on lower layers (and,
inside a subpackage, its own modules, with no circle among them).
"""

from __future__ import annotations

import ast
import textwrap
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "python" / "pupper_core"

#: From the top down. A unit imports only units of lower layers.
LAYERS: tuple[tuple[str, ...], ...] = (
    # the public face and the CLI's entry
    ("__init__", "_cli"),
    # the kinds driven in Python: recommend searches with tune's study and
    # draws its robots from a fit
    ("_recommend",),
    ("_tune", "_fit"),
    # the native-backed runs, and the backends Rust calls by name
    ("_run", "_ray", "_warp"),
    # what a run directory is shown as
    ("_report",),
    ("plots", "render"),
    # a run directory's files, lines, lock and signals
    ("_rundir",),
    # the native module's face: constants, types
    ("_spec", "_types"),
    ("_native",),
)

#: Module-size limits of issue 50: a folder of few top-level modules, no
#: source file over MAX_LINES, no function over MAX_FUNCTION.
MAX_TOP_LEVEL = 15
MAX_LINES = 600
MAX_FUNCTION = 80


def layer_of(unit: str) -> int:
    for i, units in enumerate(LAYERS):
        if unit in units:
            return i
    raise AssertionError(f"pupper_core.{unit} is on no layer: add it to LAYERS in {__file__}")


def module_name(path: Path, root: Path = PACKAGE) -> str:
    rel = path.relative_to(root).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" and len(rel.parts) > 1 else rel.parts
    return ".".join(parts)


def imports(path: Path, root: Path = PACKAGE) -> list[tuple[int, str]]:
    """(line, dotted module under pupper_core) of every import in a file."""
    here = module_name(path, root)
    package = here if path.name == "__init__.py" else here.rpartition(".")[0]
    out: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name.removeprefix("pupper_core.")) for a in node.names
                    if a.name.startswith("pupper_core.")]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".") if package else []
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            elif node.module and (node.module == "pupper_core" or node.module.startswith("pupper_core.")):
                mod = node.module.removeprefix("pupper_core").removeprefix(".")
            else:
                continue
            # `from pupper_core._fit import intervals` names a module, not a
            # name of _fit's own: the arrow goes to the module
            modules = [(node.lineno, f"{mod}.{a.name}" if mod else a.name) for a in node.names
                       if (root / (f"{mod}/{a.name}".strip("/").replace(".", "/"))).is_dir()
                       or (root / f"{(mod.replace('.', '/') + '/') if mod else ''}{a.name}.py").is_file()
                       or (root / f"{(mod.replace('.', '/') + '/') if mod else ''}{a.name}.pyi").is_file()]
            if mod and len(modules) < len(node.names):
                out.append((node.lineno, mod))
            out += modules
    return out


def unit_of(module: str) -> str:
    return module.split(".")[0] or "__init__"


def sources(root: Path = PACKAGE) -> list[Path]:
    return sorted(p for p in root.rglob("*.py") if "models" not in p.relative_to(root).parts)


def upward(root: Path = PACKAGE) -> list[str]:
    """Every import of a unit on the same or a higher layer, in words."""
    bad = []
    for path in sources(root):
        mine = unit_of(module_name(path, root))
        for line, mod in imports(path, root):
            theirs = unit_of(mod)
            if theirs == mine:
                continue
            if layer_of(theirs) <= layer_of(mine):
                bad.append(f"{path.relative_to(root)}:{line} imports pupper_core.{mod} "
                           f"({theirs}, layer {layer_of(theirs)}; {mine} is on layer {layer_of(mine)})")
    return bad


def circles(root: Path = PACKAGE) -> list[list[str]]:
    """Circles among modules (a subpackage's modules each count)."""
    graph: dict[str, set[str]] = {}
    for path in sources(root):
        me = module_name(path, root) or "__init__"
        for _, mod in imports(path, root):
            if mod != me:
                graph.setdefault(me, set()).add(mod)
    found: list[list[str]] = []
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> None:
        state[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                found.append(stack[stack.index(m):] + [m])
            elif m not in state:
                visit(m)
        stack.pop()
        state[n] = 2

    for n in sorted(graph):
        if n not in state:
            visit(n)
    return found


def test_every_unit_is_on_a_layer():
    units = {unit_of(module_name(p)) for p in sources()} | {p.stem for p in PACKAGE.glob("*.pyi")}
    for u in sorted(units):
        layer_of(u)


def test_layers_import_only_downwards():
    bad = upward()
    assert not bad, "imports back up:\n" + "\n".join(bad)


def test_no_import_circle():
    found = circles()
    assert not found, "import circles:\n" + "\n".join(" -> ".join(c) for c in found)


def test_a_staged_import_back_up_fails(tmp_path):
    # a copy of the package with one function-local import from a low layer
    # (plots) back up into the facade: the checks must name it
    import shutil

    root = tmp_path / "pupper_core"
    shutil.copytree(PACKAGE, root, ignore=shutil.ignore_patterns("*.so", "models", "__pycache__"))
    target = root / "plots" / "__init__.py"
    target.write_text(target.read_text() + textwrap.dedent("""

        def _staged() -> None:
            from pupper_core._run import sweep  # back up: plots is below the runs

            del sweep
        """))
    bad = upward(root)
    assert any("plots/__init__.py" in b and "pupper_core._run" in b for b in bad), bad
    # and a circle of two modules inside one subpackage is found
    (root / "_tune" / "tables.py").write_text((root / "_tune" / "tables.py").read_text()
                                               + "\nfrom pupper_core._tune import study\n")
    assert any({"_tune.tables", "_tune.study"} <= set(c) for c in circles(root)), circles(root)


def test_the_package_is_small_modules():
    # modules, subpackages and the native extension (its .so and .pyi one)
    top = {p.name.split(".")[0] for p in PACKAGE.iterdir()
           if p.suffix in (".py", ".pyi", ".so") or (p / "__init__.py").is_file()}
    assert len(top) <= MAX_TOP_LEVEL, sorted(top)
    long_files = [f"{p.relative_to(PACKAGE)}: {n} lines" for p in sources()
                  if (n := len(p.read_text().splitlines())) > MAX_LINES]
    assert not long_files, long_files
    long_functions = []
    for p in sources():
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1  # type: ignore[operator]
                if n > MAX_FUNCTION:
                    long_functions.append(f"{p.relative_to(PACKAGE)}:{node.lineno} {node.name}: {n} lines")
    assert not long_functions, long_functions


@pytest.mark.parametrize("unit", ["_fit", "_tune", "_recommend", "_report", "plots", "render", "_warp"])
def test_a_subpackage_keeps_its_modules_inside(unit):
    assert (PACKAGE / unit / "__init__.py").is_file()
    assert not list(PACKAGE.glob(f"{unit}_*.py")), f"{unit}'s modules belong in {unit}/"


def shadowed(root: Path = PACKAGE) -> list[str]:
    """Names a package's __init__ binds that are also its modules' names:
    ``pupper_core._fit.excite`` would then be a function to getattr (and so
    to mock.patch or monkeypatch), and the module only to ``import``."""
    bad = []
    for init in sorted(root.rglob("__init__.py")):
        subs = {p.stem for p in init.parent.glob("*.py") if p.stem != "__init__"}
        subs |= {p.name for p in init.parent.iterdir() if (p / "__init__.py").is_file()}
        for node in ast.parse(init.read_text()).body:
            if isinstance(node, ast.ImportFrom):
                # `from pupper_core._report import fit` binds the module itself
                names = [] if node.module == module_name(init, root) or node.module == (
                    "pupper_core." + module_name(init, root)) else [a.asname or a.name for a in node.names]
            elif isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                names = [node.name]
            elif isinstance(node, ast.Assign):
                names = [t.id for t in node.targets if isinstance(t, ast.Name)]
            else:
                continue
            bad += [f"{init.relative_to(root)}:{node.lineno} binds '{n}', the name of its module {n}"
                    for n in names if n in subs]
    return bad


def test_no_package_hides_its_own_module():
    assert not shadowed(), shadowed()


def test_a_staged_shadow_is_found(tmp_path):
    import shutil

    root = tmp_path / "pupper_core"
    shutil.copytree(PACKAGE, root, ignore=shutil.ignore_patterns("*.so", "models", "__pycache__"))
    init = root / "_recommend" / "__init__.py"
    init.write_text(init.read_text() + "\nfrom pupper_core._recommend.search import search\n")
    assert any("binds 'search'" in b for b in shadowed(root)), shadowed(root)
