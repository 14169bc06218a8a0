"""Values for people: mm and rad at the interfaces become um and urad in text."""
from __future__ import annotations


def human(value: float, unit: str, digits: int = 4) -> str:
    """A value in units for people: um for mm, urad for rad, with `digits` significant figures."""
    if unit == "mm":
        return f"{value * 1000:.{digits}g} um"
    if unit == "rad":
        return f"{value * 1e6:.{digits}g} urad"
    if unit.startswith("mm/"):
        return f"{value * 1000:.{digits}g} um/{unit[3:]}"
    if unit.startswith("rad/"):
        return f"{value * 1e6:.{digits}g} urad/{unit[4:]}"
    return f"{value:.{digits + 2}g} {unit}".rstrip()
