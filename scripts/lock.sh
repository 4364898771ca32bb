#!/usr/bin/env bash
# Regenerates the lock files: resolves python/requirements.txt in a
# throw-away venv and pins what it installed (python/requirements.lock);
# then, for each optional extra E with a python/requirements-E.txt, adds it
# to a fresh venv holding only the base lock and pins what it added
# (python/requirements-E.lock), so each extra installs on the base alone.
# Only `name==version` lines are kept, so an editable install, a local path
# or a URL (the project's own package, say) can never be written into a lock.
set -euo pipefail
cd "$(dirname "$0")/.."
base=${PUPPER_BASE_PYTHON:-python3}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$base" -m venv "$tmp/venv"
pip=("$tmp/venv/bin/python" -m pip -q --disable-pip-version-check)
freeze() {
  "$tmp/venv/bin/python" -m pip freeze --exclude-editable --all \
    | grep -E '^[A-Za-z0-9][A-Za-z0-9._-]*==[^ ;@]+$' \
    | grep -viE '^(pip|setuptools|wheel|pupper[-_]core)=='
}
"${pip[@]}" install -r python/requirements.txt
freeze > "$tmp/base"
{
  sed -n '1,/^# Regenerate/p' python/requirements.lock
  cat "$tmp/base"
} > "$tmp/lock"
mv "$tmp/lock" python/requirements.lock
echo "wrote python/requirements.lock ($(grep -c '==' python/requirements.lock) packages)"
for req in python/requirements-*.txt; do
  extra=${req#python/requirements-}
  extra=${extra%.txt}
  rm -rf "$tmp/venv"
  "$base" -m venv "$tmp/venv"
  "${pip[@]}" install -r python/requirements.lock
  "${pip[@]}" install -r "$req"
  freeze > "$tmp/all"
  {
    echo "# Pinned packages of the optional extra '$extra' ($req), on top of"
    echo "# python/requirements.lock: what installing it added to that venv."
    echo "# Regenerate: bash scripts/lock.sh"
    # what the extra added, in pip's order
    grep -vxF -f "$tmp/base" "$tmp/all" || true
  } > "python/requirements-$extra.lock"
  echo "wrote python/requirements-$extra.lock ($(grep -c '==' "python/requirements-$extra.lock") packages)"
done
