"""The calibration report: one self-contained HTML file a person can read without the README.

Built in two steps: `record.build` runs the analyses (diagnosis rounds, fit, sensitivity) and returns a `Report`,
a plain JSON-able record (`Report.record`, numbers in um / urad for people, keys with units) and its figures as PNG
bytes; `html.render` turns it into the page (inline CSS, figures as base64 PNG, no script, nothing fetched);
`pdf.print_pdf` prints the page with headless Chromium. `compensation.read` reads what a compensation run left
in a folder (summary.json and its maps). No jinja2: the page is built with Python string building, so the
runtime keeps its import contract.
"""
