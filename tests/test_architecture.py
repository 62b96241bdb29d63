"""The package's shape (docs/architecture.md): imports follow the data flow, no module reaches for
another's private names, the tables of kinds and units exist once, no function grows past a screen."""

import ast
import math
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src" / "robocal"

# the data flow, upstream first: a module may import from its own layer or an earlier one
LAYERS = [
    {"_version", "_base"},
    {"_model"},
    {"_identification"},
    {"_accuracy"},
    {"_simulation"},
    {"_diagnosis"},
    {"_files"},
    {"_store"},
    {"_presentation"},
    {"__init__", "errors", "kinematics", "io", "sim", "limit", "report", "identification", "store"},
    {"cli", "__main__"},
]
LAYER = {name: i for i, names in enumerate(LAYERS) for name in names}
MAX_FUNCTION_LINES = 80
MAX_CALIBRATE_LINES = 60
# the package's top: the public facades, the entry points and the version, nothing else
MAX_TOP_MODULES = 12
MAX_COMPLEXITY = 20         # radon's grade C at most


def _modules():
    return sorted(p for p in SRC.rglob("*.py"))


def _unit(path: Path) -> str:
    """The top-level part of the package a file belongs to (``_files`` for ``_files/model.py``)."""
    rel = path.relative_to(SRC).parts
    return rel[0] if len(rel) > 1 else rel[0][:-3]


def _imports(path: Path):
    """(imported top-level unit, imported names, line) for every robocal import in ``path``."""
    tree = ast.parse(path.read_text())
    package = path.relative_to(SRC).parts[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module != "__future__":
            if node.level:
                base = list(package[:len(package) - node.level + 1])
                target = base + (node.module.split(".") if node.module else [])
            elif node.module and node.module.split(".")[0] == "robocal":
                target = node.module.split(".")[1:]
            else:
                continue
            names = [a.name for a in node.names]
            if not target:                       # from . import x: x is the unit
                for n in names:
                    yield n, [], node.lineno
            else:
                yield target[0], names, node.lineno
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("robocal."):
                    yield a.name.split(".")[1], [], node.lineno


def test_the_top_of_the_package_holds_facades_and_folders_only():
    top = sorted(p.name for p in SRC.glob("*.py"))
    assert len(top) <= MAX_TOP_MODULES, top
    private = [n for n in top if n.startswith("_") and n not in ("__init__.py", "__main__.py", "_version.py")]
    assert not private, f"private modules belong in a folder: {private}"


def test_each_folder_says_what_lives_there_and_what_it_may_import():
    for init in SRC.glob("_*/__init__.py"):
        doc = ast.get_docstring(ast.parse(init.read_text()))
        assert doc and "May import:" in doc, f"{init.relative_to(SRC)} does not say what it may import"


def test_every_module_has_a_layer():
    assert {_unit(p) for p in _modules()} <= set(LAYER), {_unit(p) for p in _modules()} - set(LAYER)


def test_imports_follow_the_data_flow_and_reach_no_private_name():
    wrong = []
    for path in _modules():
        own = _unit(path)
        for unit, names, line in _imports(path):
            where = f"{path.relative_to(SRC)}:{line}"
            if unit != own and LAYER.get(unit, -1) > LAYER[own]:
                wrong.append(f"{where} imports {unit} against the data flow")
            wrong += [f"{where} imports the private name {n}" for n in names
                      if n.startswith("_") and not n.endswith("__")]
            if unit != own and unit.startswith("_") and not names:
                wrong.append(f"{where} imports the private module {unit} itself")
    assert not wrong, "\n".join(wrong)


def test_no_import_cycle():
    graph = {}
    for path in _modules():
        graph.setdefault(_unit(path), set()).update(u for u, _, _ in _imports(path) if u != _unit(path))
    seen, done = set(), set()

    def visit(node, stack):
        if node in done:
            return
        assert node not in seen, f"import cycle: {' -> '.join(stack + [node])}"
        seen.add(node)
        for nxt in graph.get(node, ()):
            visit(nxt, stack + [node])
        done.add(node)

    for node in graph:
        visit(node, [])


def test_tests_import_what_they_test_by_its_name_in_its_folder():
    """A unit test imports from the module of its folder that holds what it tests, never a private
    (underscored) name: what a test needs is that folder's own interface."""
    wrong = []
    for path in sorted((ROOT / "tests").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("robocal"):
                wrong += [f"tests/{path.name}:{node.lineno} imports {a.name} from {node.module}" for a in node.names
                          if a.name.startswith("_") and not a.name.endswith("__")]
    assert not wrong, "\n".join(wrong)


def test_no_function_over_a_screen():
    long = []
    for path in _modules():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                # the code, not its documentation: a numpy-style docstring is as long as it needs
                body = node.body[1:] if ast.get_docstring(node) is not None and len(node.body) > 1 else node.body
                n = node.end_lineno - body[0].lineno + 1
                limit = MAX_CALIBRATE_LINES if node.name == "calibrate" else MAX_FUNCTION_LINES
                if n > limit:
                    long.append(f"{path.relative_to(SRC)}:{node.lineno} {node.name}: {n} lines")
    assert not long, "\n".join(long)


def test_no_block_of_tangled_branches():
    """No function or method at cyclomatic grade D or worse (complexity above ``MAX_COMPLEXITY``):
    a reader follows each of them in one go."""
    cc = pytest.importorskip("radon.complexity", reason="radon is in the test extra")
    tangled = [f"{path.relative_to(SRC)}:{block.lineno} {block.fullname}: {block.complexity}"
               for path in _modules() for block in cc.cc_visit(path.read_text())
               if block.complexity > MAX_COMPLEXITY]
    assert not tangled, "\n".join(tangled)


# -- one table each ---------------------------------------------------------------------------------

def _dict_literals(path: Path):
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Dict):
            keys = [k.value for k in node.keys if isinstance(k, ast.Constant)]
            yield node, keys


def test_tables_of_kinds_units_and_display_units_exist_once():
    from robocal._base.units import ANGLE_UNITS, LENGTH_UNITS
    from robocal._model.parameters import KIND_QUANTITY, SI_UNITS
    from robocal._presentation.units import DISPLAY_UNITS

    assert LENGTH_UNITS["mm"] == 1e-3 and ANGLE_UNITS["deg"] == pytest.approx(math.pi / 180)
    assert set(SI_UNITS.values()) == set(DISPLAY_UNITS) and set(KIND_QUANTITY.values()) == set(SI_UNITS)
    homes = {"kinds": SRC / "_model" / "parameters.py", "units": SRC / "_base" / "units.py",
             "display": SRC / "_presentation" / "units.py"}
    kinds = {"alpha", "beta", "theta", "gamma", "d", "r", "b"}
    found = []
    for path in _modules():
        for node, keys in _dict_literals(path):
            if path != homes["units"] and ({"mm", "m"} <= set(keys) or {"deg", "rad"} <= set(keys)):
                found.append(f"{path.relative_to(SRC)}:{node.lineno} a table of units")
            if path != homes["kinds"] and len(kinds & set(keys)) >= 3:
                found.append(f"{path.relative_to(SRC)}:{node.lineno} a table of parameter kinds")
        text = path.read_text()
        if path != homes["display"] and "deg/(kN m)" in text:
            found.append(f"{path.relative_to(SRC)} a display unit of its own")
    assert not found, "\n".join(found)


def test_documents_examples_and_benchmarks_use_public_names_only():
    files = [ROOT / "README.md", *ROOT.glob("docs/*.md"), *ROOT.glob("examples/**/*.py"),
             *ROOT.glob("examples/**/*.md"), *ROOT.glob("benchmarks/*.py"), *ROOT.glob("benchmarks/*.md")]
    private = [f"{p.relative_to(ROOT)}: {m.group(0)}" for p in files
               for m in re.finditer(r"robocal\._\w+", p.read_text())]
    assert not private, "\n".join(private)


def test_the_architecture_doc_lists_every_module():
    """docs/architecture.md names each module: a top-level one in a table row, a subpackage's in its
    package's row (``_files/``, ``_presentation/``, ``cli/``); every public module in the public table."""
    doc = (ROOT / "docs" / "architecture.md").read_text()
    rows = [line for line in doc.splitlines() if line.startswith("| `")]
    named = {m for line in rows for m in re.findall(r"`([\w./]+)`", line)}
    missing = []
    for path in _modules():
        rel = path.relative_to(SRC).with_suffix("")
        if len(rel.parts) == 1:
            if rel.name == "__init__":
                continue                                  # the package itself: `robocal`
            public = not rel.name.startswith("_")
            if rel.name not in named and f"robocal.{rel.name}" not in named and f"`{rel.name}`" not in doc:
                missing.append(str(rel))
            elif public and rel.name != "__main__" and f"`robocal.{rel.name}`" not in doc:
                missing.append(f"robocal.{rel.name} (public table)")
        else:
            row = next((line for line in rows if line.startswith(f"| `{rel.parts[0]}/`")), "")
            if rel.name != "__init__" and f"`{rel.name}`" not in row:
                missing.append(str(rel))
    assert not missing, "not in docs/architecture.md: " + ", ".join(missing)


def test_every_public_module_is_an_attribute_of_a_fresh_robocal():
    import subprocess
    import sys

    code = ("import robocal as rc; "
            "[getattr(rc, m) for m in ('kinematics', 'io', 'sim', 'limit', 'report', 'errors', 'identification', "
            "'store')]")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={"PYTHONPATH": str(ROOT / "src"), "PATH": ""})
    assert run.returncode == 0, run.stderr


def test_doctests_use_public_names_only():
    """A docstring's example is what a user types: it imports from public modules only
    (``_kinematics.py``'s example joins as that module is restructured)."""
    pending = {"_kinematics.py"}
    private = [f"{p.relative_to(SRC)}: {line.strip()}" for p in _modules() if p.name not in pending
               for line in p.read_text().splitlines()
               if line.strip().startswith((">>>", "...")) and re.search(r"robocal\._\w+", line)]
    assert not private, "\n".join(private)
