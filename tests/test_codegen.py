"""Generated kernels are fresh, self-describing, written atomically, and load without SymPy."""
import os
import subprocess
import sys

import pytest

from fiveaxis_derive import codegen

from conftest import ROOT, SHIPPED


def test_committed_generated_modules_are_fresh(tmp_path):
    """Regenerating every shipped machine into a temporary folder gives byte-identical files."""
    produced = []
    for name in SHIPPED:
        produced += [p for p, _ in codegen.generate(name, tmp_path)]
    committed = sorted(p.name for p in (ROOT / "generated").glob("*.py") if p.name != "__init__.py")
    assert sorted(p.name for p in produced) == committed
    for p in produced:
        assert p.read_bytes() == (ROOT / "generated" / p.name).read_bytes(), f"{p.name} is stale: run make derive"


def test_header_names_source_hash_and_do_not_edit():
    import hashlib
    text = (ROOT / "generated" / "li2018.py").read_text()
    head = text.splitlines()[:5]
    assert "do not edit" in head[0]
    sha = hashlib.sha256((ROOT / "machines" / "li2018.toml").read_bytes()).hexdigest()
    assert f"source sha256: {sha}" in text


def test_interrupted_write_leaves_the_old_module(tmp_path, monkeypatch):
    target = tmp_path / "li2018.py"
    target.write_text("old")

    def boom(src, dst, **kw):
        raise KeyboardInterrupt

    from fiveaxis import outputs
    monkeypatch.setattr(outputs.os, "replace", boom)
    with pytest.raises(KeyboardInterrupt):
        outputs.write_text(target, "new", force=True)
    assert target.read_text() == "old"
    assert os.listdir(tmp_path) == ["li2018.py"]


def test_derive_check_detects_a_stale_module(tmp_path):
    for p, _ in codegen.generate("li2018", tmp_path):
        pass
    (tmp_path / "li2018.py").write_text((tmp_path / "li2018.py").read_text() + "# hand edit\n")
    from conftest import run_cli
    assert run_cli("derive", "li2018", "--check", "--out", str(tmp_path))[0] == 1
    assert run_cli("derive", "li2018", "--check")[0] == 0


def test_loading_a_generated_model_does_not_import_sympy():
    code = ("import sys, numpy as np, fiveaxis; m = fiveaxis.load('li2018'); m.J(0., 0., 0., 0., 0., 200.);"
            "bad = [k for k in sys.modules if k.split('.')[0] in ('sympy', 'jinja2', 'fiveaxis_derive')];"
            "print(bad); assert not bad")
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)


def test_edited_machine_file_is_derived_into_the_cache(tmp_path, monkeypatch):
    """A machine file with no fresh generated module is derived once into FIVEAXIS_CACHE, then reused."""
    src = (ROOT / "machines" / "li2018.toml").read_text().replace("length = 200.0", "length = 180.0")
    path = tmp_path / "li2018.toml"
    path.write_text(src)
    monkeypatch.setenv("FIVEAXIS_CACHE", str(tmp_path / "cache"))
    import fiveaxis
    m = fiveaxis.load(path)
    assert m.machine.tool_length == 180.0
    assert list((tmp_path / "cache").glob("li2018_*.py"))
    assert m.kernels.__file__.startswith(str(tmp_path / "cache"))


def test_derive_imports_only_the_machine_reader_of_the_runtime():
    """Every runtime module is named in the import-linter contract of the derivation (new modules too)."""
    import tomllib
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    contract = next(c for c in conf if c["source_modules"] == ["fiveaxis_derive"])
    allowed = {"fiveaxis.model.machine", "fiveaxis.exceptions", "fiveaxis.model.effect_ids", "fiveaxis.__init__",
               "fiveaxis.model.expressions", "fiveaxis.model.columns", "fiveaxis.outputs", "fiveaxis.model.provenance",
               "fiveaxis.inputs"}
    src = ROOT / "src" / "fiveaxis"
    runtime = {f"fiveaxis.{p.stem}" for p in src.glob("*.py")} | {f"fiveaxis.{p.parent.name}"
                                                                   for p in src.glob("*/__init__.py")}
    runtime |= {f"fiveaxis.model.{p.stem}" for p in (src / "model").glob("*.py") if p.stem != "__init__"}
    runtime -= {"fiveaxis.model"}
    missing = sorted(runtime - allowed - set(contract["forbidden_modules"]))
    assert not missing, f"add to the derivation contract in pyproject.toml: {missing}"


def test_derivation_loads_no_runtime_module_but_the_reader():
    code = ("import sys, fiveaxis_derive.codegen, fiveaxis_derive.table2;"
            "mods = sorted(k for k in sys.modules if k.startswith('fiveaxis.'));"
            "assert mods == ['fiveaxis.exceptions', 'fiveaxis.inputs', 'fiveaxis.model', 'fiveaxis.model.columns',"
            " 'fiveaxis.model.effect_ids', 'fiveaxis.model.expressions', 'fiveaxis.model.machine',"
            " 'fiveaxis.model.provenance', 'fiveaxis.outputs'], mods")
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)
