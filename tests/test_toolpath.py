"""LSIL along the user's own toolpath (issue 14): G-code through LinuxCNC's rs274, CSV poses, --pose, surfaces.

The reference for the G-code path is the real interpreter (its canonical output parsed here independently) and a
plain NumPy evaluation of Eq. 12-15 at the sampled poses; explicit poses (a CSV of the interpreter's sampled poses)
must give the same PL_i.
"""
import json
import math
import re
import subprocess

import numpy as np
import pytest

import fiveaxis
from fiveaxis.linuxcnc import rs274 as gcode
from fiveaxis.sensitivity import surfaces, toolpath
from conftest import run_cli
from fiveaxis.exceptions import InputError

CENTRE = np.array([50.0, 30.0, 20.0])     # sphere centre in the workpiece frame (mm), off the trunnion's axes
RADIUS = 40.0
STEP = ["--step-mm", "4", "--step-deg", "4"]


@pytest.fixture(scope="module")
def trunnion():
    return fiveaxis.load("ac_trunnion")


def sphere_pose(model, A_deg, C_deg):
    """X Y Z (mm) A C (deg) that put the tool tip (L0) on the sphere with the tool axis along the inward normal."""
    L0 = model.machine.tool_length
    A, C = math.radians(A_deg), math.radians(C_deg)
    tip0, v = model.ideal_tool(np.array([[0.0, 0.0, 0.0, A, C]]), L0)
    # the tip is affine in X, Y, Z at fixed A, C: its columns from unit moves
    M = np.column_stack([model.ideal_tool(np.array([[*e, A, C]]), L0)[0][0] - tip0[0] for e in np.eye(3)])
    xyz = np.linalg.solve(M, CENTRE - RADIUS * v[0] - tip0[0])
    return [*xyz, A_deg, C_deg]


def finishing_pass(model, inch=False) -> str:
    """A 5-axis finishing pass over the sphere: A from -10 to -60 deg while C turns 0 -> 150 deg."""
    f = 1 / 25.4 if inch else 1.0
    lines = ["(ac_trunnion: finishing pass over a sphere R40 centred at X50 Y30 Z20 of the workpiece)",
             "G20 G90 G17" if inch else "G21 G90 G17"]
    first = sphere_pose(model, -10, 0)
    lines.append("G0 X%.4f Y%.4f Z%.4f A%.4f C%.4f" % (first[0] * f, first[1] * f, first[2] * f, *first[3:]))
    lines.append("F800")
    for a, c in zip(np.linspace(-14, -60, 12), np.linspace(12, 150, 12)):
        p = sphere_pose(model, a, c)
        lines.append("G1 X%.4f Y%.4f Z%.4f A%.4f C%.4f" % (p[0] * f, p[1] * f, p[2] * f, *p[3:]))
    lines += ["G0 Z240", "M2"]
    return "\n".join(lines) + "\n"


def rs274_feeds(path):
    """Independent reading of the real interpreter's output: (kind, end point X Y Z A B C) of every straight move."""
    out = subprocess.run([gcode.RS274, "-g", str(path)], capture_output=True, text=True, check=True).stdout
    moves = []
    for m in re.finditer(r"(STRAIGHT_TRAVERSE|STRAIGHT_FEED)\(([^)]*)\)", out):
        moves.append((m.group(1), np.array([float(x) for x in m.group(2).split(",")])))
    return moves


def sample_reference(moves, step_mm, step_deg):
    """The documented sampling rule, written out again: X Y Z (mm) A C (deg) of every sample of the G1 moves."""
    prev, prev_kind, out = np.zeros(6), None, []
    for kind, end in moves:
        if kind == "STRAIGHT_FEED":
            d = end - prev
            n = max(1, math.ceil(np.linalg.norm(d[:3]) / step_mm), math.ceil(np.hypot(d[3], d[5]) / step_deg))
            for k in range(0 if prev_kind != "STRAIGHT_FEED" else 1, n + 1):
                out.append(prev + (k / n) * d if k < n else end)
        prev, prev_kind = end, kind
    return np.array(out)[:, [0, 1, 2, 3, 5]]


def numpy_pl(model, q, E, L0, LE, normals=None, order=16):
    """Eq. 12-15 in plain NumPy: W_i = int |J_iE_i . P| |J_iE_i . N| / (|J_iE_i| |P|^2) dL (normal mode 1; mode 0
    without N: int |J_iE_i . P| / |P|^2 dL), J from the kernels at each Gauss-Legendre node, LSIL = mean over the
    poses, PL = LSIL / sum."""
    x, w = np.polynomial.legendre.leggauss(order)
    nodes, weights = L0 - LE / 2 + LE / 2 * x, LE / 2 * w
    W = np.zeros((len(q), len(E)))
    for L, wt in zip(nodes, weights):
        J = model.jk(q, L)[0] * E[None, :, None]                # J_i E_i, (n, 41, 3)
        P = J.sum(axis=1)
        dot = np.abs(np.einsum("nik,nk->ni", J, P))
        p2 = np.einsum("nk,nk->n", P, P)
        if normals is None:
            W += wt * dot / p2[:, None]
        else:
            jn = np.abs(np.einsum("nik,nk->ni", J, normals))
            jj = np.linalg.norm(J, axis=2)
            W += wt * np.where(jj > 0, dot * jn / np.where(jj > 0, jj, 1), 0) / p2[:, None]
    lsil = W.mean(axis=0)
    return lsil / lsil.sum()


def run_json(capsys, argv):
    assert run_cli(*argv, "--json", echo=True)[0] == 0, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)


@pytest.fixture(scope="module")
def program(tmp_path_factory, trunnion):
    path = tmp_path_factory.mktemp("gcode") / "sphere.ngc"
    path.write_text(finishing_pass(trunnion))
    return path


def test_gcode_path_equals_explicit_poses_and_numpy(rs274, capsys, tmp_path, trunnion, program):
    argv = ["lsa", "--machine", "ac_trunnion", "--toolpath", str(program), "--surface",
            "sphere:%g,%g,%g" % tuple(CENTRE)] + STEP
    out = run_json(capsys, argv)
    # the sampled poses: the interpreter's own output, sampled by the documented rule, equal ours
    tp = toolpath.from_program(gcode.interpret(program), trunnion.machine, 4.0, 4.0)
    ref = sample_reference(rs274_feeds(program), 4.0, 4.0)
    q = tp.poses.array
    np.testing.assert_allclose(q[:, :3], ref[:, :3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.degrees(q[:, 3:]), ref[:, 3:], rtol=0, atol=1e-9)
    assert out["settings"]["poses"] == len(q) > 40 and out["settings"]["normal_mode"] == 1
    # the programmed points put the tool tip on the sphere (to the program's 4 decimals); between them the joints
    # move linearly, and the tip leaves the sphere by the chord error only
    tips, axis = trunnion.ideal_tool(q, trunnion.machine.tool_length)
    ends = [s["last_pose"] for s in out["segments"]]
    np.testing.assert_allclose(np.linalg.norm(tips[ends] - CENTRE, axis=1), RADIUS, atol=1e-3)
    assert np.all(np.abs(np.linalg.norm(tips - CENTRE, axis=1) - RADIUS) < 0.5)
    # explicit poses: a CSV of the sampled poses and their normals gives the same PL_i
    normals = surfaces.parse("sphere:%g,%g,%g" % tuple(CENTRE)).normals(tips)
    csv = tmp_path / "poses.csv"
    rows = ["X,Y,Z,A,C,nx,ny,nz"] + [",".join(repr(float(v)) for v in (*r[:3], *np.degrees(r[3:]), *n))
                                     for r, n in zip(q, normals)]
    csv.write_text("\n".join(rows) + "\n")
    explicit = run_json(capsys, ["lsa", "--machine", "ac_trunnion", "--toolpath", str(csv)])
    names = list(out["indices"])
    a = np.array([out["indices"][n] for n in names])
    b = np.array([explicit["indices"][n] for n in names])
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-15)
    # and plain NumPy Eq. 12-15 at the same poses
    E = trunnion.error_vector(None)
    ref_pl = numpy_pl(trunnion, q, E, trunnion.machine.tool_length, trunnion.machine.cutting_length, normals)
    np.testing.assert_allclose(a, [ref_pl[trunnion.errors.index(n)] for n in names], rtol=1e-9, atol=1e-15)
    # per segment: one per G1 move, labelled with the program line, covering every pose once
    segs = out["segments"]
    assert [s["label"] for s in segs] == [f"line {i}" for i in range(5, 17)]
    assert segs[0]["first_pose"] == 0 and segs[-1]["last_pose"] == len(q) - 1
    assert all(s2["first_pose"] == s1["last_pose"] + 1 for s1, s2 in zip(segs, segs[1:]))
    seg0 = np.array([segs[0]["indices"][n] for n in names])
    first = slice(segs[0]["first_pose"], segs[0]["last_pose"] + 1)
    ref0 = numpy_pl(trunnion, q[first], E, trunnion.machine.tool_length, trunnion.machine.cutting_length,
                    normals[first])
    np.testing.assert_allclose(seg0, [ref0[trunnion.errors.index(n)] for n in names], rtol=1e-9, atol=1e-15)


def test_without_normals_the_output_says_so_and_mode_0_matches_numpy(rs274, capsys, trunnion, program):
    out = run_json(capsys, ["lsa", "--machine", "ac_trunnion", "--toolpath", str(program)] + STEP)
    assert out["settings"]["normal_mode"] == 0 and "without the surface normal" in out["settings"]["normals"]
    q = toolpath.from_program(gcode.interpret(program), trunnion.machine, 4.0, 4.0).poses.array
    ref = numpy_pl(trunnion, q, trunnion.error_vector(None), trunnion.machine.tool_length,
                   trunnion.machine.cutting_length)
    names = list(out["indices"])
    np.testing.assert_allclose([out["indices"][n] for n in names], [ref[trunnion.errors.index(n)] for n in names],
                               rtol=1e-9, atol=1e-15)
    assert run_cli("lsa", "--machine", "ac_trunnion", "--toolpath", program, *STEP, echo=True)[0] == 0
    assert "normals: none: LSIL without the surface normal N" in capsys.readouterr().out


def test_inches_and_offsets_are_machine_positions_in_mm(rs274, tmp_path, trunnion):
    mm = tmp_path / "mm.ngc"
    mm.write_text(finishing_pass(trunnion))
    inch = tmp_path / "inch.ngc"
    inch.write_text(finishing_pass(trunnion, inch=True))
    a = toolpath.from_program(gcode.interpret(mm), trunnion.machine, 4.0, 4.0).poses.array
    b = toolpath.from_program(gcode.interpret(inch), trunnion.machine, 4.0, 4.0).poses.array
    assert a.shape == b.shape
    np.testing.assert_allclose(b[:, :3], a[:, :3], atol=2e-3)           # 4 decimals of an inch: 2.54 um
    np.testing.assert_allclose(b[:, 3:], a[:, 3:], atol=1e-12)          # rotary words are degrees in G20 too
    # work offset (G10 L2 / G54, set in inches) and G92: LinuxCNC's machine position = program + offsets
    off = tmp_path / "offsets.ngc"
    off.write_text("G20 G90\nG10 L2 P1 X1 Y-2 Z0.5 A-3 C10\nG54\nG0 X0 Y0 Z0 A0 C0\nG1 X2 F10\n"
                   "G21\nG92 X0\nG1 X10\nM2\n")
    p = gcode.interpret(off)
    ends = [mv.end for mv in p.moves]
    assert ends[1] == pytest.approx({"X": 25.4 * 3, "Y": -50.8, "Z": 12.7, "A": -3, "B": 0, "C": 10}, abs=1e-9)
    assert ends[2]["X"] == pytest.approx(25.4 * 3 + 10, abs=1e-9)       # G92 X0 at X 2 in: X10 mm lands 10 mm on
    assert [mv.line for mv in p.moves] == [4, 5, 8] and p.units == ["inch", "mm"]


@pytest.mark.parametrize("text, needle", [
    ("G21\nG1 X10 Q F10\nM2\n", "line 2: rs274: "),                     # the interpreter's own message
    ("G21\nG1 X10\nM2\n", "line 2: rs274: Cannot do g1 with zero feed rate"),
    ("G21\nG1 X10 F10\n", "rs274: File ended with no percent sign or program end"),
    ("G21\nG1 X500 Y0 Z0 A0 C0 F10\nM2\n", "line 2: X = 401 mm is outside the stroke [-400, 400] mm"),
    ("G21\nG1 X0 Y0 Z0 A0 B20 C0 F10\nM2\n", "line 2: the program moves B to 20, an axis ac_trunnion does not"),
    ("G21\nG1 X10 F10\nG38.2 Z-10\nM2\n", "line 3: a probing move (G38) is not sampled"),
    ("G21\nG0 X350 Y0 Z0 A0 C0\nG3 X350 Y0 I30 J0 F10\nM2\n", "line 3: X = "),          # the arc leaves the X stroke
    ("G21\nG1 X10 F10\nG2 X20 Y0 I5 J0 P0\nM2\n", "line 3: rs274: "),
    ("G21\nG0 X10\nM2\n", "no G1, G2 or G3 (feed) move"),
])
def test_bad_gcode_is_one_line(rs274, capsys, tmp_path, text, needle):
    f = tmp_path / "bad.ngc"
    f.write_text(text)
    assert run_cli("lsa", "--machine", "ac_trunnion", "--toolpath", str(f), echo=True)[0] == 2
    err = capsys.readouterr().err
    assert err.startswith("fiveaxis: error: ") and needle in err and len(err.strip().splitlines()) == 1, err
    assert str(f) in err


def test_rejected_line_is_the_source_line_even_with_n_words_and_block_delete(rs274, tmp_path):
    f = tmp_path / "n.ngc"
    f.write_text("G21\n(comment)\nN100 G1 X1 F10\n/N7 G1 X2\n\nN5 G1 X3 Q\nM2\n")
    with pytest.raises(InputError, match=r"line 6: rs274: .*\(N5 G1 X3 Q\)"):
        gcode.interpret(f)
    assert "N3 G1" in gcode.tag_lines("G21\n\nN100 G1 X1") and "/N2 " in gcode.tag_lines("G21\n/G1 X1")


@pytest.mark.parametrize("text, needle", [
    ("X,Y,Z,A,B\n0,0,0,0,0\n", "column B is not an axis of ac_trunnion"),              # li2018's axes
    ("X,Y,Z,A\n0,0,0,0\n", "column C is missing"),
    ("X,Y,Z,A,C,nx,ny,nz\n0,0,0,0,0,0,0,0\n", "row 2: the surface normal (nx, ny, nz) has zero length"),
    ("X,Y,Z,A,C,nx,ny\n0,0,0,0,0,0,1\n", "a normal needs all three of nx, ny, nz"),
    ("X,Y,Z,A,C\n0,0,0,0,0\n0,0,0,-150,0\n", "row 3: A = -150 deg is outside the stroke [-120, 30] deg"),
    ("X,Y,Z,A,C\n0,0,nan,0,0\n", "row 2, column Z: expected a finite number"),
    ("X,Y,Z,A,C\n", "no poses"),
])
def test_bad_csv_toolpath_is_one_line(capsys, tmp_path, text, needle):
    f = tmp_path / "path.csv"
    f.write_text(text)
    assert run_cli("lsa", "--machine", "ac_trunnion", "--toolpath", str(f), echo=True)[0] == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1, err


def test_explicit_poses_and_their_errors(capsys, trunnion):
    out = run_json(capsys, ["lsa", "--machine", "ac_trunnion", "--pose", "X=10,Y=20,Z=100,A=-30,C=45",
                            "--pose", "X=-50,Y=0,Z=150,A=-90,C=120"])
    assert out["settings"]["poses"] == 2 and [s["label"] for s in out["segments"]] == ["pose 1", "pose 2"]
    q = np.array([[10, 20, 100, math.radians(-30), math.radians(45)], [-50, 0, 150, math.radians(-90),
                                                                          math.radians(120)]])
    ref = numpy_pl(trunnion, q, trunnion.error_vector(None), 150.0, 25.0)
    assert out["indices"]["ez_A"] == pytest.approx(ref[trunnion.errors.index("ez_A")], rel=1e-9)
    for spec, needle in [("X=1,Y=2,Z=3,A=0", "C is missing"), ("X=1,Y=2,Z=3,A=0,C=0,B=1", "B is not an axis"),
                         ("X=1,Y=2,Z=3,A=0,C=0,nx=0,ny=0,nz=0", "zero length"),
                         ("X=1e300,Y=2,Z=3,A=0,C=0", "outside the stroke")]:
        assert run_cli("lsa", "--machine", "ac_trunnion", "--pose", spec, echo=True)[0] == 2
        err = capsys.readouterr().err
        assert needle in err and len(err.strip().splitlines()) == 1, err


def test_surfaces_give_outward_unit_normals():
    from fiveaxis.sensitivity import paper as presets
    phi = np.radians([-45.0, 0.0, 80.0])
    # the paper's cone: apex on the axis above the part, radius growing downwards, half-angle 30 deg
    cone = surfaces.parse("cone:0,0,%r,0,0,-1,30" % (200 * math.tan(math.radians(60))))
    pts = np.column_stack([150 * np.cos(phi), 150 * np.sin(phi), np.full(3, 50 * math.tan(math.radians(60)))])
    np.testing.assert_allclose(cone.normals(pts), presets.cone_normals(phi), atol=1e-12)
    np.testing.assert_allclose(surfaces.parse("plane:0,0,2").normals(pts), [[0, 0, 1]] * 3)
    np.testing.assert_allclose(surfaces.parse("sphere:1,1,1").normals(np.array([[1, 1, 3.0]])), [[0, 0, 1]])
    np.testing.assert_allclose(surfaces.parse("cylinder:0,0,0,0,0,1").normals(np.array([[0, 2, 5.0]])), [[0, 1, 0]])
    for bad, needle in [("sphere:1,2", "3 numbers"), ("torus:1", "expected sphere"), ("plane:0,0,0", "zero"),
                        ("cone:0,0,0,0,0,1,90", "half-angle"), ("sphere:a,b,c", "numbers")]:
        with pytest.raises(InputError, match=needle):
            surfaces.parse(bad)
    with pytest.raises(InputError, match="undefined at contact point 2"):
        surfaces.parse("sphere:0,0,0").normals(np.array([[1.0, 0, 0], [0, 0, 0]]))


def test_surface_normal_undefined_on_the_path_is_one_line(rs274, capsys, trunnion, program):
    # the sphere's centre put at the tool tip of the first sample: no normal there
    tp = toolpath.from_program(gcode.interpret(program), trunnion.machine, 4.0, 4.0)
    tip = trunnion.ideal_tool(tp.poses.array[:1], trunnion.machine.tool_length)[0][0]
    assert run_cli("lsa", "--machine", "ac_trunnion", "--toolpath", program, "--surface",
                   "sphere:%r,%r,%r" % tuple(float(t) for t in tip), *STEP, echo=True)[0] == 2
    err = capsys.readouterr().err
    assert "normal is undefined at contact point 1" in err and len(err.strip().splitlines()) == 1


def test_path_compensation_and_plots(rs274, capsys, tmp_path, program):
    assert run_cli("lsa", "--machine", "ac_trunnion", "--toolpath", program, "--surface",
                   "sphere:%g,%g,%g" % tuple(CENTRE), "--compensate", "--plot", tmp_path, "--json", *STEP,
                   echo=True)[0] == 0
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    comp = out["compensation"]
    rows = {r["scenario"]: r for r in comp["machining_error_mm"]}
    assert rows["all halved"]["improvement_pct"] == pytest.approx(50.0)     # first order: linear in E
    assert comp["measure"].startswith("|N . P_err|") and 1 <= len(comp["vital"]) <= 10
    assert set(comp["vital"]) == set(out["ranking"][:len(comp["vital"])])
    written = {p.name for p in tmp_path.iterdir()}
    assert written == {"lsa_path_pie.png", "lsa_path_shares.png", "lsa_path_compensation.png"}
    assert all(f"fiveaxis: wrote {tmp_path / n}" in captured.err for n in written)


# --- arcs (G2/G3) ------------------------------------------------------------------------------------------------

def arc_poses(tmp_path, trunnion, text, step=1.0):
    """Sampled poses (X Y Z mm, A C deg) and segment numbers of a program."""
    f = tmp_path / "arc.ngc"
    f.write_text(text)
    tp = toolpath.from_program(gcode.interpret(f), trunnion.machine, step, step)
    q = tp.poses.array.copy()
    q[:, 3:] = np.degrees(q[:, 3:])
    return q, tp.segment, tp.labels


def swept(p, centre, e1, e2):
    """Unwrapped angle (rad) of points p about centre, measured from axis e1 towards e2 (closed form)."""
    d = p - centre
    return np.unwrap(np.arctan2(d @ e2, d @ e1))


def check_spacing(p, r, step):
    """The documented rule, checked on the result: consecutive samples at most step mm apart and their chords
    within toolpath.CHORD_FRACTION * step of the circle of radius r."""
    chords = np.linalg.norm(np.diff(p, axis=0), axis=1)
    assert chords.max() <= step + 1e-9
    half = np.arcsin(np.clip(chords / (2 * r), 0, 1))
    assert np.all(r * (1 - np.cos(half)) <= toolpath.CHORD_FRACTION * step + 1e-12)


EX, EY, EZ = np.eye(3)


def test_full_circle_quarter_arc_and_helix_in_g17(rs274, tmp_path, trunnion):
    q, seg, labels = arc_poses(tmp_path, trunnion, "G21 G90 G17\nG0 X30 Y20 Z-5 A0 C0\n"
                               "G2 X30 Y20 I-10 J0 F100\n"             # full circle, clockwise, centre (20, 20)
                               "G3 X20 Y30 I-10 J0\n"                  # quarter, counter-clockwise
                               "G2 X20 Y30 Z15 I0 J-10 P2\n"           # helix: two clockwise turns, Z -5 -> 15
                               "M2\n")
    c = np.array([20.0, 20.0, -5.0])
    assert labels == ("line 3", "line 4", "line 5")
    circle, quarter, helix = (q[seg == k, :3] for k in range(3))
    # distance R from the centre (to rs274's 4 decimals), in the plane Z = -5 for the first two
    for p in (circle, quarter):
        np.testing.assert_allclose(np.linalg.norm(p - c, axis=1), 10.0, atol=1e-4)
        np.testing.assert_allclose(p[:, 2], -5.0, atol=1e-12)
        check_spacing(p, 10.0, 1.0)
    np.testing.assert_allclose(np.hypot(helix[:, 0] - 20, helix[:, 1] - 20), 10.0, atol=1e-4)
    # direction and extent seen from +Z: G2 clockwise a whole turn, G3 counter-clockwise a quarter, P2 two turns
    a = swept(circle, c, EX, EY)
    assert np.all(np.diff(a) < 0) and a[-1] - a[0] == pytest.approx(-2 * math.pi, abs=1e-9)
    b = swept(np.vstack([circle[-1:], quarter]), c, EX, EY)
    assert np.all(np.diff(b) > 0) and b[-1] - b[0] == pytest.approx(math.pi / 2, abs=1e-9)
    h = swept(np.vstack([quarter[-1:], helix]), c, EX, EY)
    assert h[-1] - h[0] == pytest.approx(-4 * math.pi, abs=1e-9)
    # angle linear in the parameter: equal angle steps; the polyline of n equal chords is 2 n R sin(pi / n)
    n = len(circle) - 1
    np.testing.assert_allclose(np.diff(a), -2 * math.pi / n, atol=1e-9)
    length = np.linalg.norm(np.diff(circle, axis=0), axis=1).sum()
    assert length == pytest.approx(2 * n * 10 * math.sin(math.pi / n), rel=1e-12)
    half = math.acos(1 - toolpath.CHORD_FRACTION * 1.0 / 10)        # the largest half-angle the chord rule allows
    assert 2 * math.pi * 10 * math.sin(half) / half <= length < 2 * math.pi * 10
    # the helix: Z linear in the angle swept, -5 -> 15 over -4 pi
    z = np.concatenate([quarter[-1:, 2], helix[:, 2]])
    np.testing.assert_allclose(z, -5 + 20 * (h - h[0]) / (-4 * math.pi), atol=1e-9)


def test_g18_g19_planes_and_inches(rs274, tmp_path, trunnion):
    # G18: the plane Z, X (normal Y); G2 clockwise seen from +Y. G19: Y, Z (normal X); G3 counter-clockwise from +X
    q, seg, _ = arc_poses(tmp_path, trunnion, "G21 G90\nG0 X10 Y5 Z0 A0 C0\n"
                          "G18 G2 X-10 Z0 I-10 K0 F100\n"             # centre (0, 5, 0), R 10, through Z +10
                          "G19 G3 Y5 Z20 J0 K10\n"                     # from (-10, 5, 0): centre (-10, 5, 10)
                          "M2\n")
    xz = q[seg == 0, :3]
    assert np.all(xz[:, 1] == 5.0)
    np.testing.assert_allclose(np.hypot(xz[:, 0], xz[:, 2]), 10.0, atol=1e-4)
    a = swept(xz, np.array([0.0, 5, 0]), EZ, EX)                   # about +Y: from Z towards X
    assert np.all(np.diff(a) < 0) and a[-1] - a[0] == pytest.approx(-math.pi, abs=1e-9)
    assert xz[len(xz) // 2, 2] > 9.9                                # clockwise from +Y: over Z = +10
    yz = np.vstack([xz[-1:], q[seg == 1, :3]])
    assert np.all(yz[:, 0] == -10.0)
    np.testing.assert_allclose(np.hypot(yz[:, 1] - 5, yz[:, 2] - 10), 10.0, atol=1e-4)
    b = swept(yz, np.array([-10.0, 5, 10]), EY, EZ)                # about +X: from Y towards Z
    assert np.all(np.diff(b) > 0) and b[-1] - b[0] == pytest.approx(math.pi, abs=1e-9)
    # G20: the same circle in inches is 25.4 times larger, in mm
    q, seg, _ = arc_poses(tmp_path, trunnion, "G20 G90 G17\nG0 X1 Y0 Z0 A0 C0\nG2 X1 Y0 I-1 J0 F10\nM2\n")
    np.testing.assert_allclose(np.hypot(q[:, 0], q[:, 1]), 25.4, atol=1e-9)
    check_spacing(q[:, :3], 25.4, 1.0)


def test_r_format_work_offset_rotation_and_g92(rs274, tmp_path, trunnion):
    # G54 at (100, 50, -20) turned 30 deg; an R-format half circle about program (0, 0), then after G92 X0 Y0 an
    # I J half circle whose centre is the same point: machine positions turn about (100, 50)
    q, seg, _ = arc_poses(tmp_path, trunnion, "G21 G90 G17\nG10 L2 P1 X100 Y50 Z-20 R30\nG54\n"
                          "G0 X20 Y0 Z0 A0 C0\nG2 X-20 Y0 R20 F100\nG92 X0 Y0\nG3 X40 Y0 I20 J0\n"
                          "G18 G3 X40 Z20 I0 K10\nM2\n")              # the XZ plane turned 30 deg about Z
    c = np.array([100.0, 50.0, -20.0])
    t = math.radians(30)

    def machine(x, y):
        return c + [x * math.cos(t) - y * math.sin(t), x * math.sin(t) + y * math.cos(t), 0]

    g2, g3 = q[seg == 0, :3], q[seg == 1, :3]
    np.testing.assert_allclose(g2[0], machine(20, 0), atol=1e-9)
    np.testing.assert_allclose(g2[-1], machine(-20, 0), atol=1e-9)
    np.testing.assert_allclose(g3[-1], machine(20, 0), atol=1e-9)
    for p in (g2, g3):
        np.testing.assert_allclose(np.linalg.norm(p - c, axis=1), 20.0, atol=1e-4)
    # both pass program (0, -20): G2 clockwise from angle 0, G3 counter-clockwise from angle pi
    a = swept(g2, c, EX, EY)
    assert a[-1] - a[0] == pytest.approx(-math.pi, abs=1e-9)
    b = swept(np.vstack([g2[-1:], g3]), c, EX, EY)
    assert b[-1] - b[0] == pytest.approx(math.pi, abs=1e-9)
    low = machine(0, -20)
    assert min(np.linalg.norm(g2 - low, axis=1)) < 1.0 and min(np.linalg.norm(g3 - low, axis=1)) < 1.0
    # G18 under the rotation: a half circle R10 about machine(20, 0) + 10 Z in the plane of Z and the turned X
    xz = np.vstack([g3[-1:], q[seg == 2, :3]])
    cz = machine(20, 0) + [0, 0, 10]
    ux, normal = np.array([math.cos(t), math.sin(t), 0]), np.array([-math.sin(t), math.cos(t), 0])
    np.testing.assert_allclose(np.linalg.norm(xz - cz, axis=1), 10.0, atol=1e-4)
    np.testing.assert_allclose((xz - cz) @ normal, 0.0, atol=1e-9)
    a = swept(xz, cz, EZ, ux)
    assert np.all(np.diff(a) > 0) and a[-1] - a[0] == pytest.approx(math.pi, abs=1e-9)


def test_an_arc_moves_the_rotary_axes_linearly(rs274, tmp_path, trunnion):
    q, seg, _ = arc_poses(tmp_path, trunnion, "G21 G90 G17\nG0 X10 Y0 Z0 A-10 C20\n"
                          "G3 X0 Y10 I-10 J0 A-40 C-70 F100\nM2\n")
    a = swept(q[:, :3], np.zeros(3), EX, EY)
    f = (a - a[0]) / (math.pi / 2)                                  # fraction of the angle swept
    np.testing.assert_allclose(q[:, 3], -10 - 30 * f, atol=1e-9)
    np.testing.assert_allclose(q[:, 4], 20 - 90 * f, atol=1e-9)
    assert len(q) - 1 >= 90                                         # C moves 90 deg in steps of at most 1 deg
    assert np.abs(np.diff(q[:, 3:], axis=0)).max() <= 1 + 1e-9


def arc_reference(path, step):
    """The interpreter's output read again here (G17, no offsets, mm) and sampled by the documented rule written
    out again: X Y Z (mm) A C (deg) of every sample of the G1, G2 and G3 moves."""
    out = subprocess.run([gcode.RS274, "-g", str(path)], capture_output=True, text=True, check=True).stdout
    prev, prev_cut, rows = np.zeros(6), False, []
    for m in re.finditer(r"(STRAIGHT_TRAVERSE|STRAIGHT_FEED|ARC_FEED)\(([^)]*)\)", out):
        v = np.array([float(x) for x in m.group(2).split(",")])
        if m.group(1) == "ARC_FEED":
            end = np.array([v[0], v[1], v[5], v[6], v[7], v[8]])
            cx, cy, rot = v[2], v[3], int(v[4])
            th0 = math.atan2(prev[1] - cy, prev[0] - cx)
            th1 = math.atan2(end[1] - cy, end[0] - cx)
            r0, r1 = math.hypot(prev[0] - cx, prev[1] - cy), math.hypot(end[0] - cx, end[1] - cy)
            if rot > 0:                                                  # counter-clockwise, in (0, 2 pi]
                sweep = (th1 - th0) % (2 * math.pi) or 2 * math.pi
            else:                                                        # clockwise, in [-2 pi, 0)
                sweep = -((th0 - th1) % (2 * math.pi) or 2 * math.pi)
            sweep += 2 * math.pi * (abs(rot) - 1) * np.sign(rot)
            r = max(r0, r1)
            tol = toolpath.CHORD_FRACTION * step
            n = max(1, math.ceil(math.hypot(r * abs(sweep) + abs(r1 - r0), end[2] - prev[2]) / step),
                    math.ceil(np.hypot(end[3] - prev[3], end[5] - prev[5]) / step),
                    math.ceil(abs(sweep) / (2 * math.acos(1 - tol / r))))
            for k in range(0 if not prev_cut else 1, n + 1):
                t = k / n
                th, rr = th0 + t * sweep, r0 + t * (r1 - r0)
                rows.append(end if k == n else np.concatenate([
                    [cx + rr * math.cos(th), cy + rr * math.sin(th)], prev[2:] + t * (end[2:] - prev[2:])]))
            prev_cut = True
        else:
            end = v
            if m.group(1) == "STRAIGHT_FEED":
                d = end - prev
                n = max(1, math.ceil(np.linalg.norm(d[:3]) / step), math.ceil(np.hypot(d[3], d[5]) / step))
                rows += [prev + (k / n) * d if k < n else end for k in range(0 if not prev_cut else 1, n + 1)]
            prev_cut = m.group(1) == "STRAIGHT_FEED"
        prev = end
    return np.array(rows)[:, [0, 1, 2, 3, 5]]


def test_lsil_along_arcs_equals_numpy_on_poses_built_independently(rs274, capsys, tmp_path, trunnion):
    f = tmp_path / "arcs.ngc"
    f.write_text("G21 G90 G17\nG0 X40 Y-10 Z60 A-20 C0\nF500\nG1 X40 Y0\n"
                 "G3 X0 Y40 I-40 J0 Z50 A-45 C90\n"                   # a quarter helix turning A and C
                 "G2 X-20 Y20 R20\n"                                   # R format
                 "G2 X-20 Y20 I20 J0 P2 Z70 C-30\n"                    # two turns about (0, 20)
                 "G0 Z200\nM2\n")
    out = run_json(capsys, ["lsa", "--machine", "ac_trunnion", "--toolpath", str(f)] + STEP)
    q = toolpath.from_program(gcode.interpret(f), trunnion.machine, 4.0, 4.0).poses.array
    ref = arc_reference(f, 4.0)
    assert q.shape == ref.shape and len(q) > 100
    np.testing.assert_allclose(q[:, :3], ref[:, :3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.degrees(q[:, 3:]), ref[:, 3:], rtol=0, atol=1e-9)
    qr = ref.copy()
    qr[:, 3:] = np.radians(qr[:, 3:])
    pl = numpy_pl(trunnion, qr, trunnion.error_vector(None), trunnion.machine.tool_length,
                  trunnion.machine.cutting_length)
    names = list(out["indices"])
    assert out["settings"]["poses"] == len(ref)
    np.testing.assert_allclose([out["indices"][n] for n in names], [pl[trunnion.errors.index(n)] for n in names],
                               rtol=1e-9, atol=1e-15)
    assert [s["label"] for s in out["segments"]] == ["line 4", "line 5", "line 6", "line 7"]
