#!/usr/bin/env bash
# List the reports (HTML, PDF where Chromium printed one, DCC XML) in a folder, with absolute paths. No PDF is not an
# error (a machine without Chromium writes HTML only).
set -euo pipefail
dir=${1:?folder}
for f in "$dir"/*.html "$dir"/*.pdf "$dir"/*.xml; do
    if [ -e "$f" ]; then echo "    $(cd "$(dirname "$f")" && pwd)/$(basename "$f")"; fi
done
