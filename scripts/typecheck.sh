#!/usr/bin/env bash
# mypy over the import package as it installs. pyproject.toml maps the top-level folders into
# ``ctdrill`` (package-dir), which mypy cannot read, so the package is laid out as a tree of
# links in a scratch folder inside the venv (never in the repository) and checked from there.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
venv=${1:-$repo/.venv}
tree="$venv/typecheck"
rm -rf "$tree/ctdrill" "$tree/bench"
mkdir -p "$tree/ctdrill"
for f in "$repo"/ctdrill/*; do ln -s "$f" "$tree/ctdrill/"; done
for d in app engine imaging model haptics assets; do ln -s "$repo/$d" "$tree/ctdrill/$d"; done
ln -s "$repo/bench" "$tree/bench"
cd "$tree"
exec "$venv/bin/mypy" --config-file "$repo/pyproject.toml"
