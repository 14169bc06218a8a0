"""Per-position error profiles `<param>:<var>k<spacing>` and `kT<n>` (issue 22): the grammar, the family against np.interp,
the fitted-model file, LinuxCNC's compensation files read as LinuxCNC reads them; and the issue's lead-screw axis:
an irregular per-target error (random values at 9 targets, 30 um spread) plus a 25 um reversal on an ISO 230-2
log written as it arrives (0.001 mm, 0.1 um): diagnose offers the profile at its 9 targets, with it and the reversal the residual
is at the noise, and the comp file written from them, applied by the simulator, leaves the noise."""
from dataclasses import dataclass

import numpy as np
import pytest

import fiveaxis
from fiveaxis.compensation import folder as CF
from fiveaxis.compensation import pipeline as CP
from fiveaxis.compensation.record import summary
from fiveaxis.diagnosis import diagnose as D
from fiveaxis.effects import families as fx
from fiveaxis.estimation import fit as F
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.exceptions import InputError
from fiveaxis.iso230 import positioning as P
from fiveaxis.linuxcnc import configuration as lx
from fiveaxis.measurement import instruments as ins
from fiveaxis.measurement.files import read
from fiveaxis.measurement.simulate import simulate, to_frame
from fiveaxis.report import text

NOISE = 1e-3


@pytest.fixture(scope="module")
def model():
    return fiveaxis.load("ac_trunnion")


def test_grammar_and_knots(model):
    fam, parts = fx.split("dx_x:xk100", ["x", "y", "z", "A", "C", "t"])
    assert (fam.NAME, parts, fam.format(*parts)) == ("profile", ("dx_x", "x", 100.0), "dx_x:xk100")
    assert fx.split("dx_x:tk100", ["x", "t"]) is None and fx.split("dx_x:xk0", ["x"]) is None
    assert "k<spacing>" in fx.explain("dx_x:xq5", ["x"])
    eff = fx.parse("dx_x:xk100", model.machine, model.errors)
    assert eff.knots == tuple(float(k) for k in range(-400, 401, 100))
    assert eff.names[0] == "dx_x:xk100@-400" and len(eff.names) == 9
    c = fx.parse("ez_C:Ck45", model.machine, model.errors)          # a rotary axis: knots in degrees
    assert c.knots[0] == -180.0 and c.knots[-1] == 180.0 and len(c.knots) == 9
    assert len(fx.parse("dx_x:xk300", model.machine, model.errors).knots) == 4     # -400 ... 500: past the end
    with pytest.raises(InputError, match=r"801 knots over the stroke \[-400, 400\] mm \(expected at most 256"):
        fx.parse("dx_x:xk1", model.machine, model.errors)
    assert "a per-position positioning error profile of X" in eff.describe(model.machine)


def test_basis_against_np_interp(model):
    eff = fx.parse("dy_x:xk150", model.machine, model.errors)
    x = np.linspace(-450, 450, 301)                                 # beyond the stroke: the end values held
    poses = np.zeros((len(x), 5))
    poses[:, 0] = x
    B = eff.basis(fx.context(model.machine, poses))
    knots = np.array(eff.knots)
    ref = np.column_stack([np.interp(x, knots, np.eye(len(knots))[j]) for j in range(len(knots))])
    assert np.allclose(B, ref, atol=1e-15)
    rot = fx.parse("ez_C:Ck45", model.machine, model.errors)
    poses = np.zeros((7, 5))
    poses[:, 4] = np.radians([-180, -100, -10, 0, 33, 90, 180])
    ref = np.column_stack([np.interp(np.degrees(poses[:, 4]), rot.knots, np.eye(9)[j]) for j in range(9)])
    assert np.allclose(rot.basis(fx.context(model.machine, poses)), ref, atol=1e-12)


def test_comp_file_read_as_linuxcnc_reads_it(tmp_path):
    p = tmp_path / "a.comp"
    p.write_text("-400 0.001 0.002\n0 0 0\n400 -0.001 0.001\n# trailing comment\n5000 1 1\n")
    nominal, fwd, rev = lx.read_comp_file(p)
    assert list(nominal) == [-400, 0, 400] and list(rev) == [0.002, 0.0, 0.001]
    p.write_text("# a header makes LinuxCNC's table empty\n-400 0 0\n400 0 0\n")
    with pytest.raises(InputError, match=r"line 1: expected 'nominal forward reverse'"):
        lx.read_comp_file(p)
    p.write_text("0 0 0\n100 0 0\n100 0 0\n")
    with pytest.raises(InputError, match="line 3: nominal 100 does not increase"):
        lx.read_comp_file(p)


# -- the lead-screw axis ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TargetErrors:
    """A test-only effect: the positioning error of X given at the targets, linear in between (np.interp)."""
    targets: tuple
    id: str = "lead_screw"
    param: str = "dx_x"

    @property
    def names(self):
        return tuple(f"lead_screw@{i}" for i in range(len(self.targets)))

    def basis(self, ctx):
        x = ctx.poses[:, list(ctx.variables).index("X")]
        n = len(self.targets)
        return np.column_stack([np.interp(x, self.targets, np.eye(n)[j]) for j in range(n)])


@pytest.fixture(scope="module")
def lead_screw(model, tmp_path_factory):
    plan = ins.plan("interferometer", model, 0, np.random.default_rng(31), targets=9, axes=["X"])
    targets = tuple(np.unique(plan.poses[:, 0]))
    v = np.random.default_rng(32).uniform(-1, 1, 9)
    values = 0.030 * (v - v.min()) / np.ptp(v) - 0.015                   # 30 um spread
    effects = [(TargetErrors(targets), values), "dx_x:xr=0.0125"]         # + a 25 um reversal
    sim = simulate(model, effects, noise=NOISE, seed=33, plan=plan)
    df = to_frame(sim, model)
    df["X"] = df["X"].round(3)
    df["du"] = df["du"].round(4)
    path = tmp_path_factory.mktemp("lead") / "laser_x.csv"
    df.to_csv(path, index=False)
    return plan, effects, read(path, model.machine), path


def test_lead_screw_profile_offered_and_residual_at_the_noise(model, lead_screw):
    _, _, meas, _ = lead_screw
    first = D.diagnose(model, meas, top=5)
    assert first.missing_effect and "dx_x:xr" in {i for c in first.candidates for i in (c["id"], *c["aliases"])}
    dg = D.diagnose(model, meas, ["dx_x:xr"], top=3)
    top = dg.candidates[0]
    assert dg.missing_effect and top["id"] == "dx_x:xkT9" and top["family"] == "profile"    # at the 9 targets
    assert len(top["coefficients"]) == 9 and top["rms_mm"] <= 1.25 * NOISE
    after = D.diagnose(model, meas, ["dx_x:xr", "dx_x:xkT9"], top=3)
    assert after.verdict == "no missing effect" and after.rms_mm_without_outliers <= 1.25 * NOISE
    j = after.to_json()                          # the model's profile printed as its table (the fit's record)
    (t,) = j["profiles"]
    assert t["id"] == "dx_x:xkT9" and f"{t['id']} (E_XX): the positioning error of X at its 9 knots, {t['datum']}" \
        in text.diagnosis(j)
    # the polynomials do not get there: a cubic with the reversal leaves structure
    poly = F.fit(model, meas, ["dx_x:xr", "dx_x:x1", "dx_x:x2", "dx_x:x3"])
    assert poly.rms_mm > 3 * NOISE


def test_lead_screw_comp_file_leaves_the_noise(model, lead_screw, tmp_path):
    plan, effects, meas, _ = lead_screw
    res = F.fit(model, meas, ["dx_x:xr", "dx_x:xk100"])
    fm = MF.from_fit(res)
    path = MF.save(fm, tmp_path / "model.json")
    fm = MF.load(path)                                                # through the file
    assert [e.kind for e in fm.effects] == ["reversal", "profile"] and fm.effects[1].arg == 100.0
    comp = CP.compensate(fm, model, counts={v: 9 if v == "X" else 2 for v in model.variables}, poses=200)  # X: knots
    (tmp_path / "comp").mkdir()
    CF.write(comp, tmp_path / "comp", summary(comp))
    nominal, fwd, rev = lx.read_comp_file(tmp_path / "comp" / "linuxcnc" / "joint0-X.comp")
    assert list(nominal) == list(range(-400, 401, 100))               # the trims sit at the profile's knots
    assert np.median(fwd - rev) == pytest.approx(-0.025, abs=0.001)    # the reversal: forward 25 um below reverse
    before = simulate(model, effects, noise=NOISE, seed=33, plan=plan)
    after = simulate(model, effects, noise=NOISE, seed=33, plan=plan,
                     commands=CF.linuxcnc_function(tmp_path / "comp", model))
    spread = lambda du: float(np.sqrt(np.mean((du - du.mean()) ** 2)))      # noqa: E731  (the dead path aside)
    assert spread(before.meas.du) > 10 * NOISE
    assert spread(after.meas.du) <= 1.25 * NOISE
    (ev,) = P.evaluate(after.meas, model)
    assert ev.figures["B"] < 3 * NOISE and ev.figures["E"] < 5 * NOISE


def test_lead_screw_through_the_command_line(model, lead_screw, tmp_path, capsys):
    from conftest import run_cli
    _, _, _, path = lead_screw
    rc, out, err = run_cli("diagnose", path, "--machine", "ac_trunnion", "--add", "dx_x:xr", "--top", "2")
    assert rc == 0, err
    assert "1. dx_x:xkT9" in out and "a per-position positioning error profile of X" in out
    rc, out, err = run_cli("fit", path, "--machine", "ac_trunnion", "--add", "dx_x:xr", "--add",
                           "dx_x:xkT9", "-o", tmp_path / "m.json")
    assert rc == 0, err
    rc, out, err = run_cli("compensate", tmp_path / "m.json", "-o", tmp_path / "c", "--nodes",
                           "X=9,Y=2,Z=2,A=2,C=2", "--poses", "100")
    assert rc == 0, err
    rc, out, err = run_cli("simulate", "--machine", "ac_trunnion", "--instrument", "interferometer",
                           "--axes", "X", "--targets", "9", "--effect", "dx_x:xr=0.0125", "--seed", "3", "-o",
                           tmp_path / "after.csv", "--compensation", tmp_path / "c", "--linuxcnc")
    assert rc == 0 and "compensated by LinuxCNC with" in err, err
    rc, _, err = run_cli("simulate", "--machine", "ac_trunnion", "--effect", "dx_x:xk100=0.01", "-o",
                         tmp_path / "x.csv")
    assert rc == 2 and "--effect dx_x:xk100=0.01: a profile needs its value at each of its 9 knots (-400, -300" in err
    rc, _, err = run_cli("simulate", "--machine", "ac_trunnion", "--linuxcnc", "-o", tmp_path / "x.csv")
    assert rc == 2 and "--linuxcnc applies the LinuxCNC files of a compensation folder" in err
