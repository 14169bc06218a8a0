"""The map is enforced: one import-linter `layers` contract over the runtime's packages. It holds on the code, and it
bites: a probe module placed in a lower package that imports a higher one makes `lint-imports` fail (on a copy of
the source tree, so that the checkout is never touched)."""
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
LINT = Path(sys.executable).with_name("lint-imports")


def _copy(tmp_path: Path) -> Path:
    """The runtime, the derivation and the generated kernels under their import names, and the contracts."""
    pkgs = tmp_path / "pkgs"
    shutil.copytree(ROOT / "src" / "fiveaxis", pkgs / "fiveaxis", ignore=shutil.ignore_patterns("__pycache__"))
    for name, folder in (("fiveaxis_derive", "derive"), ("fiveaxis_generated", "generated")):
        shutil.copytree(ROOT / folder, pkgs / name, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    return pkgs


def _lint(tmp_path: Path, pkgs: Path):
    env = {"PYTHONPATH": str(pkgs), "PATH": "/usr/bin:/bin"}
    return subprocess.run([str(LINT), "--config", str(tmp_path / "pyproject.toml")], cwd=tmp_path, env=env,
                          capture_output=True, text=True)


@pytest.fixture()
def tree(tmp_path):
    if not LINT.exists():
        pytest.skip(f"lint-imports is not installed beside {sys.executable}")
    return tmp_path, _copy(tmp_path)


def test_the_layers_hold_on_the_code(tree):
    tmp_path, pkgs = tree
    r = _lint(tmp_path, pkgs)
    assert r.returncode == 0, r.stdout[-3000:]
    assert "The runtime in layers" in r.stdout and "KEPT" in r.stdout


@pytest.mark.parametrize("lower, higher", [("model", "fiveaxis.diagnosis.diagnose"),
                                           ("estimation", "fiveaxis.report.text"),
                                           ("measurement", "fiveaxis.sensitivity.indices")])
def test_a_probe_importing_upwards_breaks_the_contract(tree, lower, higher):
    """A new module is covered without editing a list: the probe is a module nobody named."""
    tmp_path, pkgs = tree
    (pkgs / "fiveaxis" / lower / "probe_upwards.py").write_text(f'"""A probe."""\nimport {higher}  # noqa: F401\n')
    r = _lint(tmp_path, pkgs)
    assert r.returncode != 0
    assert f"fiveaxis.{lower}.probe_upwards -> {higher}" in r.stdout, r.stdout[-3000:]


def _imports(root: Path) -> dict:
    """{module: the runtime's modules it imports}, imports inside functions counted (an import moved into a function
    to break a cycle still is one)."""
    import ast
    mods = {}
    for p in root.rglob("*.py"):
        parts = p.relative_to(root.parent).with_suffix("").parts
        mods[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    graph = {}
    for name, p in mods.items():
        pkg = name if p.name == "__init__.py" else name.rpartition(".")[0]
        deps = set()
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = pkg.split(".")[:len(pkg.split(".")) - node.level + 1] if node.level else []
                target = ".".join(base + ([node.module] if node.module else []))
                deps |= {f"{target}.{a.name}" if f"{target}.{a.name}" in mods else target for a in node.names}
            elif isinstance(node, ast.Import):
                deps |= {a.name for a in node.names}
        graph[name] = {d for d in deps if d in mods and d != name}
    return graph


def test_no_module_imports_one_that_imports_it_back():
    """No circle between the runtime's modules (report/html.py and report/iso230_3.py imported each other, one import
    inside a function breaking it: the shared pieces are report/markup.py now)."""
    graph = _imports(ROOT / "src" / "fiveaxis")
    circles = []
    for start in graph:                       # a path from a module back to itself, depth first
        seen, todo = set(), [(start, [start])]
        while todo:
            node, path = todo.pop()
            for nxt in graph[node]:
                if nxt == start:
                    circles.append(" -> ".join(path + [start]))
                elif nxt not in seen:
                    seen.add(nxt)
                    todo.append((nxt, path + [nxt]))
    assert circles == []


def test_the_map_names_every_package_and_the_modules_of_the_growing_ones():
    """docs/architecture.md's map names every package of the runtime (iso230/ was missing), and every module of the
    packages that grow with each feature (diagnosis/heat.py and rounds.py were missing)."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    block = text[text.index("```"):text.index("```", text.index("```") + 3)]
    src = ROOT / "src" / "fiveaxis"
    packages = sorted(p.name for p in src.iterdir() if (p / "__init__.py").exists())
    assert [p for p in packages if f"{p}/" not in block] == []
    modules = [f"{pkg}/{m.stem}" for pkg in ("diagnosis", "report", "iso230", "effects")
               for m in sorted((src / pkg).glob("*.py")) if m.stem != "__init__"]
    assert [m for m in modules if m.split("/")[1] not in block] == []


def test_every_package_of_the_source_is_in_the_wheel():
    """pyproject.toml lists the packages the wheel holds: a package of src/ missing there installs a package that
    cannot import (measurement/instruments/ was missing: `make test-scale`'s installed wheel failed at start)."""
    import tomllib
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    src = ROOT / "src"
    found = {".".join(p.parent.relative_to(src).parts) for p in src.rglob("__init__.py")}
    assert found <= listed, sorted(found - listed)
