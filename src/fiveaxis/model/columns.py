"""The columns of a measurement file, as data: name, unit, kind, meaning, what a cell may hold, what it needs.

One table for the two readers that need it: the measurement reader validates a file against it in one loop
(`fiveaxis.measurement.files.read`), and the machine-file reader refuses an axis named like one of its columns
(`fiveaxis.model.machine`). Beside the table's columns a file has the machine's pose variables (mm for linear axes,
degrees for rotary ones), `dir_<VAR>` (+1 or -1: the direction in which that axis last moved) and temperature
channels `temp_<name>` (degC, one reading per row, blank: not read; `temperature_column`).
Units: mm, degrees in files; rad for tool-axis readings and their sigma; s for time; degC for temperatures.
"""
from __future__ import annotations

from dataclasses import dataclass

FRAMES = ("workpiece", "machine")
SETUP_KINDS = ("point", "rigid", "planar")
#: Plausibility limits: beyond them a value is not a measurement of a machine tool (an error, not a warning).
MAX_DEVIATION_MM = 1000.0          # a deviation above a metre
MAX_AXIS_DEVIATION = 2.0           # difference of two unit vectors
MAX_TOOL_LENGTH_MM = 1e5
#: The least step between two tool lengths (mm): a controller's resolution (100 and 100.0000000001 are one tool).
MIN_LENGTH_STEP_MM = 1e-3
MAX_TIME_S = 1e9
SIGMA_RANGE_MM = (1e-9, 1e3)
SIGMA_AXIS_RANGE_RAD = (1e-12, 1.0)
#: Prefix of the approach-direction columns (dir_X).
DIRECTION_PREFIX = "dir_"
#: Prefix of the temperature channels (temp_spindle, degC).
TEMPERATURE_PREFIX = "temp_"
#: A temperature column's whole name: the prefix and a checked identifier (it names a kinematics-module input and a
#: HAL signal in the files a controller reads).
TEMPERATURE_RE = r"temp_[a-z][a-z0-9_]{0,31}"
#: Temperatures a machine tool's sensors read (degC): beyond them a value is not a temperature reading.
TEMPERATURE_RANGE_DEGC = (-50.0, 200.0)


@dataclass(frozen=True)
class Column:
    """One column of a measurement file."""
    name: str
    unit: str                  # mm, 1, rad, s, or text
    meaning: str
    kind: str = "number"       # number or text
    blank: bool = True         # a blank cell is allowed (not measured, not given)
    bound: tuple | None = None  # (lo, hi) every value must lie in (of |value| when absolute)
    absolute: bool = False
    bound_text: str = ""       # what the bound means, for the error
    values: tuple = ()         # the texts allowed (text columns)
    needs: tuple = ()          # columns that must be in the file with it
    group: str = ""            # tip, axis, line (readings), direction, sigma, pose, setup


def _deviation(name, axis):
    return Column(name, "mm", f"tool-tip deviation along {axis} (actual minus nominal)", bound=(0.0, MAX_DEVIATION_MM),
                  absolute=True, bound_text=f"a deviation above {MAX_DEVIATION_MM:g} mm is not a measurement of a "
                                            f"machine tool (mm expected)", group="tip")


def _axis_deviation(name, axis):
    return Column(name, "1", f"tool-axis deviation along {axis} (actual minus nominal unit vector)",
                  bound=(0.0, MAX_AXIS_DEVIATION), absolute=True, bound_text="a change of a unit vector is at most 2",
                  group="axis")


COLUMNS = (
    Column("L", "mm", "tool length (default: the machine file's L0)", blank=False, bound=(0.0, MAX_TOOL_LENGTH_MM),
           bound_text=f"expected a tool length from 0 to {MAX_TOOL_LENGTH_MM:g} mm", group="pose"),
    Column("t", "s", "time since the start of the measurement", blank=False, bound=(0.0, MAX_TIME_S), absolute=True,
           bound_text=f"expected a time in s within +-{MAX_TIME_S:g}", group="pose"),
    _deviation("dx", "x"), _deviation("dy", "y"), _deviation("dz", "z"),
    _axis_deviation("di", "x"), _axis_deviation("dj", "y"), _axis_deviation("dk", "z"),
    Column("du", "mm", "1-D deviation along ux, uy, uz (ballbar, interferometer, tracker)",
           bound=(0.0, MAX_DEVIATION_MM), absolute=True,
           bound_text=f"a deviation above {MAX_DEVIATION_MM:g} mm is not a measurement of a machine tool (mm "
                      f"expected)", needs=("ux", "uy", "uz"), group="line"),
    Column("ux", "1", "x component of the unit direction of du", group="direction"),
    Column("uy", "1", "y component of the unit direction of du", group="direction"),
    Column("uz", "1", "z component of the unit direction of du", group="direction"),
    Column("sigma", "mm", "standard deviation of each of the row's dx, dy, dz and du", bound=SIGMA_RANGE_MM,
           bound_text=f"expected a standard deviation from {SIGMA_RANGE_MM[0]:g} to {SIGMA_RANGE_MM[1]:g} mm",
           group="sigma"),
    Column("sigma_axis", "rad", "standard deviation of each of the row's di, dj, dk", bound=SIGMA_AXIS_RANGE_RAD,
           bound_text=f"expected a standard deviation from {SIGMA_AXIS_RANGE_RAD[0]:g} to "
                      f"{SIGMA_AXIS_RANGE_RAD[1]:g} rad", group="sigma"),
    Column("setup", "text", "an artefact placement: its unknown offset is fitted beside the machine's errors",
           kind="text", group="setup"),
    Column("setup_kind", "text", "what a setup's placement may do: offset only, rigid, planar", kind="text",
           values=SETUP_KINDS, needs=("setup",), group="setup"),
    Column("setup_frame", "text", "the frame a setup is fixed in", kind="text", values=FRAMES, needs=("setup",),
           group="setup"),
    Column("frame", "text", "the frame of the deviations and directions (one for the whole file)", kind="text",
           values=FRAMES),
)
BY_NAME = {c.name: c for c in COLUMNS}


def temperature_column(name: str) -> Column:
    """The column of a temperature channel `temp_<name>` (degC; a blank cell: not read in that row)."""
    lo, hi = TEMPERATURE_RANGE_DEGC
    return Column(name, "degC", f"temperature of the sensor {name[len(TEMPERATURE_PREFIX):]} (degC; blank: not read)",
                  bound=TEMPERATURE_RANGE_DEGC,
                  bound_text=f"expected a temperature from {lo:g} to {hi:g} degC (a sensor's reading in degrees "
                             f"Celsius)", group="temperature")
#: Names of the readings, by kind.
DEVIATIONS = tuple(c.name for c in COLUMNS if c.group == "tip")
AXIS_DEVIATIONS = tuple(c.name for c in COLUMNS if c.group == "axis")
DIRECTION = tuple(c.name for c in COLUMNS if c.group == "direction")
LINE = "du"
READINGS = DEVIATIONS + AXIS_DEVIATIONS + (LINE,)
#: Names an axis of a machine file may not have (they are columns of measurement files).
RESERVED = tuple(c.name for c in COLUMNS)
