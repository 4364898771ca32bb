#!/usr/bin/env bash
# Sets up everything pupper needs on a fresh machine, idempotently:
#   1. system libraries for offscreen rendering (EGL), via apt-get if missing
#   2. the project venv .venv with every Python package pinned
#   3. the pupper_core Python module (maturin, into .venv)
#   4. the pupper binary (target/release/pupper), linked to .venv's Python
# Re-running it only redoes what changed.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
say() { printf '\033[1msetup:\033[0m %s\n' "$*" >&2; }

# 1. EGL for mujoco.Renderer. Only rendering needs it; everything else works without.
if ! ldconfig -p 2>/dev/null | grep -q 'libEGL.so.1'; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    say "installing EGL and Mesa (apt-get) for offscreen rendering"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libegl1 libgl1 libgl1-mesa-dri >/dev/null
  else
    say "warning: no libEGL; rendering will be unavailable (install libegl1 libgl1-mesa-dri)"
  fi
fi

# 2. The venv. Its base interpreter must have a shared libpython (pyo3 embeds it).
base=${PUPPER_BASE_PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  say "creating .venv with $($base --version 2>&1) ($(command -v "$base"))"
  "$base" -m venv .venv
fi
lock=python/requirements.lock
stamp=.venv/.pupper-lock
if ! cmp -s "$lock" "$stamp" 2>/dev/null; then
  say "installing pinned Python packages ($lock)"
  .venv/bin/python -m pip install -q --disable-pip-version-check -r "$lock"
  cp "$lock" "$stamp"
fi

# 3 and 4. Build against the venv's interpreter.
export PYO3_PYTHON="$root/.venv/bin/python"
say "building the pupper_core Python module"
log=.venv/maturin.log
if ! (cd python && VIRTUAL_ENV="$root/.venv" "$root/.venv/bin/maturin" develop --release) >"$log" 2>&1; then
  cat "$log" >&2
  say "error: building the Python module failed (full log above, also in $log)"
  exit 1
fi
say "building the pupper binary"
cargo build --release -q -p pupper_cli
say "ready: target/release/pupper ($(target/release/pupper --version))"
