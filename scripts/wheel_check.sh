#!/usr/bin/env bash
# The package as a user gets it: build the wheel, install it into a fresh venv in a scratch
# folder, and run `ctdrill demo` there (outside the checkout, so nothing is found by accident).
set -euo pipefail
python=${1:-python3}
repo=$(cd "$(dirname "$0")/.." && pwd)
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
"$repo/.venv/bin/python" -m pip wheel -q --no-deps --wheel-dir "$scratch/dist" "$repo"
wheel=$(ls "$scratch"/dist/ctdrill-*.whl)
tops=$(unzip -Z1 "$wheel" | cut -d/ -f1 | grep -v '\.dist-info$' | sort -u | tr '\n' ' ')
if [ "$tops" != "ctdrill " ]; then
  echo "error: $wheel installs top-level names '$tops'; only 'ctdrill' is allowed" >&2
  exit 1
fi
"$python" -m venv "$scratch/venv"
"$scratch/venv/bin/python" -m pip install -q -q "$wheel"
cd "$scratch"
"$scratch/venv/bin/ctdrill" --help >/dev/null
"$scratch/venv/bin/ctdrill" demo --out "$scratch/demo-out"
for f in force.csv profile.csv summary.json force.png; do
  test -s "$scratch/demo-out/$f" || { echo "error: the installed demo wrote no $f" >&2; exit 1; }
done
echo "wheel check: $(basename "$wheel") installs ctdrill only; the installed demo ran from $scratch"
