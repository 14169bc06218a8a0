"""The HTML pieces every section of the report is built from (`fiveaxis.report.html`, the ISO 230-3 section of
`fiveaxis.report.iso230_3`): escaped text, units for people, the record's numbers with their keys (a test checks
each against the JSON record), figures as base64 PNG and tables. Strings in, escaped HTML out; nothing imported
from the sections, so that every section module can use them without a cycle."""
from __future__ import annotations

import base64
import re
from html import escape as _escape


def escape(text) -> str:
    """Any text as HTML (quotes too: safe inside attributes)."""
    return _escape(str(text), quote=True)


def prose(text) -> str:
    """Escaped prose whose ASCII units (um, urad) are shown as people write them (µm, µrad)."""
    return escape(re.sub(r"(?<=[0-9] )u(m|rad)\b", "\u00b5\\1", str(text)))


def unit(unit: str) -> str:
    """um -> µm, urad -> µrad for people (also inside 'urad/mm')."""
    return unit.replace("urad", "\u00b5rad").replace("um", "\u00b5m") if unit else ""


def get(rec: dict, key: str):
    """The value at a dotted key of the record ("fit.parameters.3.value": list items by index)."""
    obj = rec
    for part in key.split("."):
        obj = obj[int(part)] if isinstance(obj, list) else obj[part]
    return obj


def number(rec: dict, key: str, fmt: str = ".4g", scale: float = 1.0) -> str:
    """A number of the record for people: `<data value="the record's value" data-k="its key" data-f="format">` around
    the value (times scale: 1e3 for mm -> um, 100 for a share in %) formatted; an en dash for None. Every number
    the page shows from the record goes through here, so a test can check each against the JSON record."""
    value = get(rec, key)
    if value is None:
        return "&ndash;"
    x = f' data-x="{scale!r}"' if scale != 1.0 else ""
    return (f'<data value="{float(value)!r}" data-k="{escape(key)}" data-f="{fmt}"{x}>'
            f"{format(value * scale if scale != 1.0 else value, fmt)}</data>")


def code_name(name: str, iso_name) -> str:
    """A parameter's name (and its ISO 230 name) in code type."""
    return f'<span class="code">{escape(name)}</span>' + (f' <span class="code">({escape(iso_name)})</span>'
                                                          if iso_name else "")


def figure(figures: dict, key: str, alt: str, caption: str) -> str:
    """The figure `key` of figures (PNG bytes) inline, with its caption (already escaped); "" without it."""
    if key not in figures:
        return ""
    data = base64.b64encode(figures[key]).decode("ascii")
    return (f'<figure id="fig-{escape(key)}"><img alt="{escape(alt)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{caption}</figcaption></figure>")


def table(head: list[str], rows: list[list[str]], table_id: str = "", numeric=(), row_class=None) -> str:
    """A table from already escaped cells; columns in `numeric` are right-aligned."""
    ths = "".join(f'<th class="num">{h}</th>' if i in numeric else f"<th>{h}</th>" for i, h in enumerate(head))
    body = []
    for r, row in enumerate(rows):
        cls = f' class="{row_class[r]}"' if row_class and row_class[r] else ""
        tds = "".join(f'<td class="num">{c}</td>' if i in numeric else f"<td>{c}</td>" for i, c in enumerate(row))
        body.append(f"<tr{cls}>{tds}</tr>")
    ident = f' id="{table_id}"' if table_id else ""
    return f"<table{ident}><thead><tr>{ths}</tr></thead><tbody>{''.join(body)}</tbody></table>"
