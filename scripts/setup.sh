#!/usr/bin/env bash
# Sets up everything pupper needs on a fresh machine, idempotently, from the
# checkout this script sits in (found at run time, never a fixed path):
#   1. system libraries for offscreen rendering (EGL), via apt-get if missing
#   2. the project venv .venv with every third-party Python package pinned
#   3. the pupper_core Python module (maturin, into .venv), built from this clone
#   4. the pupper binary (target/$PUPPER_PROFILE/pupper), linked to .venv's Python
# PUPPER_PROFILE=debug builds without optimisation (quicker to build, slower to
# run: the fresh-clone check uses it). PUPPER_EXTRAS=gpu,ray (comma-separated)
# also installs optional extras, pinned in python/requirements-<extra>.lock:
# gpu is MuJoCo Warp for `--backend warp`, ray is Ray for `--ray` (and, for its
# tests' loopback cluster, unshare/nsenter/ip/pkill via apt-get if missing).
# Re-running it only redoes what changed.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
# ldconfig (below) and dpkg's helpers live in sbin, which a plain user PATH
# (a fresh machine's, scripts/fresh-env's) leaves out
PATH="$PATH:/usr/local/sbin:/usr/sbin:/sbin"
profile=${PUPPER_PROFILE:-release}
case $profile in
  release) release=(--release) ;;
  debug) release=() ;;
  *) echo "setup: PUPPER_PROFILE must be release or debug, not '$profile'" >&2; exit 2 ;;
esac
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

# The ray tests run their cluster in namespaces of its own: unshare and
# nsenter (util-linux), ip (iproute2), pkill (procps).
if [[ ",${PUPPER_EXTRAS:-}," == *,ray,* ]]; then
  missing=()
  for tool in unshare:util-linux nsenter:util-linux ip:iproute2 pkill:procps; do
    command -v "${tool%%:*}" >/dev/null || missing+=("${tool#*:}")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
      say "installing ${missing[*]} (apt-get) for the Ray tests' loopback cluster"
      apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
    else
      say "warning: the Ray tests need ${missing[*]} (apt-get install ${missing[*]})"
    fi
  fi
fi

# The report tests open report.html in headless Chromium (Debian's package):
# installed with the tests' own extra, dev, which `make test` asks for.
if [[ ",${PUPPER_EXTRAS:-}," == *,dev,* ]] && ! command -v chromium >/dev/null; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    say "installing chromium (apt-get) for the report tests"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
  else
    say "warning: the report tests need chromium (apt-get install chromium)"
  fi
fi

# 2. The venv. Its base interpreter must have a shared libpython (pyo3 embeds it).
base=${PUPPER_BASE_PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  if ! "$base" -c 'import sys, sysconfig; sys.exit(sys.version_info < (3, 11) or not sysconfig.get_config_var("Py_ENABLE_SHARED"))' 2>/dev/null; then
    say "error: $base is not Python >= 3.11 with a shared libpython; set PUPPER_BASE_PYTHON to one that is"
    exit 2
  fi
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
IFS=',' read -r -a extras <<< "${PUPPER_EXTRAS:-}"
for extra in ${extras[@]+"${extras[@]}"}; do
  [ -n "$extra" ] || continue
  lock=python/requirements-$extra.lock
  if [ ! -f "$lock" ]; then
    known=$(ls python/requirements-*.lock | sed 's/.*requirements-//; s/\.lock$//' | paste -sd, -)
    say "error: PUPPER_EXTRAS names '$extra', which is no optional extra (known: $known)"
    exit 2
  fi
  stamp=.venv/.pupper-lock-$extra
  if ! cmp -s "$lock" "$stamp" 2>/dev/null; then
    say "installing the optional extra '$extra' ($lock)"
    .venv/bin/python -m pip install -q --disable-pip-version-check -r "$lock"
    cp "$lock" "$stamp"
  fi
done

# 3 and 4. Build against the venv's interpreter.
export PYO3_PYTHON="$root/.venv/bin/python"
say "building the pupper_core Python module ($profile)"
log=.venv/maturin.log
# the module is one abi3 library now: a version-tagged one left by an older
# build would shadow it on import
rm -f python/pupper_core/_native.cpython-*.so
if ! (cd python && VIRTUAL_ENV="$root/.venv" "$root/.venv/bin/maturin" develop ${release[@]+"${release[@]}"}) >"$log" 2>&1; then
  cat "$log" >&2
  say "error: building the Python module failed (full log above, also in $log)"
  exit 1
fi
say "building the pupper binary ($profile)"
cargo build ${release[@]+"${release[@]}"} -q -p pupper_cli
say "ready: target/$profile/pupper ($(target/"$profile"/pupper --version))"
