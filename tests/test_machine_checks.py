"""Machine files from a careless or hostile user (issue 13): reserved names, non-physical directions and strokes,
names that would reach generated code. Every refusal is one line naming the file and the key."""
import pytest

from conftest import run_cli
from fiveaxis.exceptions import InputError
from fiveaxis.model.machine import MACHINES_DIR, load_machine

from conftest import DATA

LI = (MACHINES_DIR / "li2018.toml").read_text()


def first(old, new):
    return lambda s: s.replace(old, new, 1)


@pytest.mark.parametrize("edit, key, expect", [
    # machine names become module names in fiveaxis_generated (`__init__` crashed with AttributeError)
    (first('name = "li2018"', 'name = "__init__"'), "name", "no Python keyword"),
    (first('name = "li2018"', 'name = "import"'), "name", "no Python keyword"),
    (first('name = "li2018"', 'name = "li2018__printed"'), "name", "single underscores"),
    (first('name = "li2018"', 'name = "_private"'), "name", "starts with a letter"),
    (first('name = "li2018"', 'name = "li2018\\n"'), "name", "li2018\\n"),
    (first('[conventions.printed]', '[conventions."p\\"\\"\\"\\nimport os"]'), "conventions.p", "expected a name"),
    (first('[conventions.printed]', '[conventions.class]'), "conventions.class", "no Python keyword"),
    # axis names that measurement files use as columns, or that mean something else in effect expressions
    (first('axis = "X"', 'axis = "L"'), "tool_chain[0].axis", "column name of measurement files"),
    (first('axis = "X"', 'axis = "t"'), "tool_chain[0].axis", "column name of measurement files"),
    (first('axis = "X"', 'axis = "dx"'), "tool_chain[0].axis", "column name of measurement files"),
    (first('axis = "X"', 'axis = "sigma"'), "tool_chain[0].axis", "column name of measurement files"),
    (first('axis = "X"', 'axis = "frame"'), "tool_chain[0].axis", "column name of measurement files"),
    (first('axis = "X"', 'axis = "T"'), "tool_chain[0].axis", "read as 't'"),
    (first('axis = "X"', 'axis = "P1"'), "tool_chain[0].axis", "read as 'p1'"),
    (first('axis = "X"', 'axis = "PI"'), "tool_chain[0].axis", "read as 'pi'"),
    (first('axis = "A"', 'axis = "exp"'), "tool_chain[4].axis", "read as 'exp'"),
    (first('axis = "A"', 'axis = "x"'), "tool_chain[4].axis", "both 'x' in effect expressions"),
    (first('axis = "X"', 'axis = "X\\n"'), "tool_chain[0].axis", "letters and digits"),
    (first('Sxy = "rz"', 'L = "rz"'), "tool_chain[1].pige.L", "tool length"),
    # directions: zero, tiny (denormal: `SVD did not converge` downstream), not finite
    (first("direction = [0, 1, 0]", "direction = [0, 1e-300, 0]"), "tool_chain[1].direction", "norm 1e-300"),
    (first("direction = [0, 1, 0]", "direction = [0, 1e-7, 0]"), "tool_chain[1].direction", "norm >= 1e-06"),
    (first("direction = [0, 0, -1]", "direction = [0, 0, -1e-300]"), "tool.direction", "norm"),
    (first("direction = [0, 0, -1]", "direction = [0, 0, 1e308, 1]"), "tool.direction", "three numbers"),
    (first("direction = [0, 0, -1]", "direction = [1.5e308, 1.5e308, 0]"), "tool.direction", "norm inf"),
    # strokes and lengths of absurd magnitude
    (first("stroke = [-2500, 2500]", "stroke = [-1e300, 1e300]"), "tool_chain[0].stroke", "beyond +-100000 mm"),
    (first("stroke = [-30, 30]", "stroke = [-1e6, 30]"), "tool_chain[3].stroke", "beyond +-3600 deg"),
    (first("stroke = [-2500, 2500]", "stroke = [0, 1e-9]"), "tool_chain[0].stroke", "shorter than"),
    (first("length = 200.0", "length = 1e300"), "tool.length", "beyond"),
    (first("cutting_length = 30.0", "cutting_length = 1e300"), "tool.cutting_length", "beyond"),
    (first("linear = 1e-4", "linear = 1e300"), "errors.linear", "beyond"),
    (first("angular = 1e-4", "angular = 3.0"), "errors.angular", "beyond"),
    (first("angular = 1e-4", "angular = 1e-4\nvalues = { ex_x = 2.0 }"), "errors.values.ex_x", "beyond"),
    (first("angular = 1e-4", "angular = 1e-4\nvalues = { dx_x = 1e4 }"), "errors.values.dx_x", "beyond"),
    (first("angular = 1e-4", "angular = 1e-4\nvalues = { Sxy = 2.0 }"), "errors.values.Sxy", "beyond"),
])
def test_bad_machine_files_are_one_line_errors(tmp_path, capsys, edit, key, expect):
    path = tmp_path / "bad.toml"
    path.write_text(edit(LI))
    with pytest.raises(InputError) as exc:
        load_machine(path)
    msg = str(exc.value)
    assert "\n" not in msg and str(path) in msg and key in msg and expect in msg, msg
    assert run_cli("gsa", "--machine", str(path), echo=True)[0] == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fiveaxis: error: ") and str(path) in err


@pytest.mark.parametrize("edit", [
    first("direction = [0, 1, 0]", "direction = [0, 2.5, 0]"),
    first("direction = [0, 1, 0]", "direction = [0, 1e-5, 0]"),
    first("stroke = [-2500, 2500]", "stroke = [-1e5, 1e5]"),
    first("stroke = [-30, 30]", "stroke = [-3600, 3600]"),
    lambda s: s.replace('axis = "X"', 'axis = "U"', 1).replace("\nX = [-2500", "\nU = [-2500", 1),
])
def test_harmless_variants_still_load(tmp_path, edit):
    path = tmp_path / "ok.toml"
    path.write_text(edit(LI))
    m = load_machine(path)
    for d in [a.direction for a in m.axes] + [m.tool_direction]:
        assert abs(sum(v * v for v in d) - 1) < 1e-15        # directions are normalised


def test_directions_are_normalised():
    m = load_machine(DATA / "nutating.toml")
    assert m.axis("B").direction == pytest.approx((0, 2 ** -0.5, 2 ** -0.5), abs=2.3e-16)   # [0, 1, 1] in the file; 1 ulp


def test_file_name_cannot_inject_code_into_a_generated_module(tmp_path):
    """The file name is written into the header comment of the module: a line break in it must not end the
    comment (a machine file named 'x\\nimport os...' would otherwise add a line of code)."""
    import ast

    from fiveaxis_derive import codegen
    path = tmp_path / "p\nimport os; os.makedirs('PWNED')\n#.toml"
    path.write_text((DATA / "planar.toml").read_text())
    out = tmp_path / "out"
    (module, _), = codegen.generate(load_machine(path), out)
    tree = ast.parse(module.read_text())
    imported = {a.name for node in ast.walk(tree) if isinstance(node, ast.Import) for a in node.names}
    assert "os" not in imported
    # the name is reduced to a safe alphabet (outputs.comment_text): the line break and the quotes become '_'
    assert module.read_text().splitlines()[1].startswith("# machine: planar (p_import os_ os.makedirs__PWNED__")
