#!/usr/bin/env bash
# Proves the README's set-up works from a clone that is not this checkout:
#   1. clones REV (default HEAD) of the repository this script sits in into a
#      fresh temporary directory (../shared, the reference data beside the
#      checkout, is not copied: the set-up must not need it);
#   2. hides this checkout: in a private mount namespace an empty tmpfs is
#      mounted over it, so any absolute path into it fails there;
#   3. there, in the clone, with no variable or PATH entry pointing into this
#      checkout, runs `PUPPER_PROFILE=debug make sweep` (the README's set-up
#      and default sweep; debug builds are quicker end to end);
#   4. runs a 2-cell sweep with the binary it built and checks its summary.csv.
#
#   scripts/check-fresh-clone.sh [REV]
#
# It tests REV as committed: uncommitted changes are not part of the check.
# pip's download cache (~/.cache/pip) and cargo's registry (~/.cargo) are used
# as they are; the rest (the venv, target/) is built from scratch, which takes
# minutes. The temporary directory is removed on exit, failure included.
# Exit status: 0 the set-up works from the clone; 1 it does not (the failing
# stage is named); 2 bad usage; 77 it cannot run here (it needs root on Linux
# and unshare(1) with mount namespaces), with the reason printed.
set -euo pipefail

t0=${FRESH_CLONE_T0:-$(date +%s)}
elapsed() { local s=$(($(date +%s) - t0)); printf '%dm%02ds' $((s / 60)) $((s % 60)); }
say() { printf 'fresh-clone [%s]: %s\n' "$(elapsed)" "$*"; }
fail() { printf 'fresh-clone [%s]: FAILED: %s\n' "$(elapsed)" "$*" >&2; exit 1; }
skip() { printf 'fresh-clone: skipped: %s\n' "$*"; exit 77; }

# Second half: in the private mount namespace (see the end of the first half).
#   --inside REPO TMP [OTHER_SPELLINGS_OF_REPO...]
if [ "${1-}" = --inside ]; then
  repo=$2 tmp=$3
  clone=$tmp/pupper
  spellings=("$repo" "${@:4}")

  mount -t tmpfs -o size=1m,mode=0755 pupper-hidden "$repo" \
    || skip "could not mount a tmpfs over $repo to hide it"
  [ -z "$(ls -A "$repo")" ] || fail "$repo is still visible after mounting a tmpfs over it"
  say "hidden: $repo is an empty directory here"
  cd "$clone"

  # Nothing from the calling shell or make may point into the hidden checkout.
  under() {  # under VALUE: does VALUE name the checkout or a path inside it?
    local r
    for r in "${spellings[@]}"; do
      case $1 in "$r" | "$r"/* | *:"$r" | *:"$r"/* | *:"$r":* | "$r":* | *=*"$r"/* | *" $r"/*) return 0 ;; esac
    done
    return 1
  }
  dropped=()
  for name in VIRTUAL_ENV PYO3_PYTHON PUPPER_BIN PUPPER_PYTHON PUPPER_PROFILE CARGO_TARGET_DIR \
    CARGO_BUILD_TARGET_DIR MAKEFLAGS MAKELEVEL MFLAGS MAKEOVERRIDES PYTHONPATH PYTHONHOME OLDPWD; do
    if [ -n "${!name+set}" ]; then dropped+=("$name"); unset "$name"; fi
  done
  for name in $(compgen -e); do
    case $name in PATH | HOME | PWD) continue ;; esac
    if under "${!name-}"; then dropped+=("$name"); unset "$name" 2>/dev/null || true; fi
  done
  IFS=: read -r -a entries <<<"$PATH"
  path=
  for p in "${entries[@]}"; do
    if under "$p"; then dropped+=("PATH entry $p"); else path=${path:+$path:}$p; fi
  done
  export PATH=$path
  export PUPPER_PROFILE=debug CARGO_INCREMENTAL=0
  say "environment: dropped ${dropped[*]:-nothing}; kept HOME=$HOME (pip and cargo caches)"
  # and nothing else a fresh machine would not set (PYTHONUNBUFFERED, say):
  # only HOME, that PATH and the two settings above reach the clone's commands
  for name in $(compgen -e); do
    case $name in HOME | PATH | PUPPER_PROFILE | CARGO_INCREMENTAL) ;; *) unset "$name" 2>/dev/null || true ;; esac
  done

  say "set-up and default sweep: PUPPER_PROFILE=debug make sweep (in $clone)"
  make sweep || fail "PUPPER_PROFILE=debug make sweep failed in the fresh clone (exit $?; its output is above)"

  bin=target/debug/pupper
  if [ ! -x "$bin" ] && [ -x target/release/pupper ]; then
    say "note: this revision's set-up ignores PUPPER_PROFILE; using target/release/pupper"
    bin=target/release/pupper
  fi
  [ -x "$bin" ] || fail "make sweep succeeded but built no $bin"

  say "python module: .venv's pupper_core must come from the clone"
  mod=$(.venv/bin/python -c 'import pupper_core; print(pupper_core.__file__)') \
    || fail ".venv/bin/python cannot import pupper_core"
  case $mod in "$clone"/*) ;; *) fail "pupper_core imports from $mod, not from the clone $clone" ;; esac

  out=$tmp/two
  say "2-cell sweep: $bin sweep --grid kp=5,30 --seconds 1 -o $out -q"
  "$bin" sweep --grid kp=5,30 --seconds 1 -o "$out" -q \
    || fail "the 2-cell sweep with $bin failed (exit $?)"
  csv=$out/summary.csv
  [ -s "$csv" ] || fail "the 2-cell sweep wrote no $csv"
  lines=$(wc -l <"$csv")
  if [ "$lines" -ne 3 ] || ! head -n 1 "$csv" | grep -q 'kp'; then
    cat "$csv" >&2
    fail "$csv should hold a header (with kp) and 2 rows; it has $lines lines (above)"
  fi
  say "summary.csv: a header and 2 rows"
  exit 0
fi

# First half: clone, then re-run this script (a copy) in a private mount namespace.
[ $# -le 1 ] || { echo "usage: $0 [REV]" >&2; exit 2; }
rev=${1:-HEAD}
here=$(dirname "${BASH_SOURCE[0]}")/..
repo=$(cd "$here" && pwd -P)
logical=$(cd "$here" && pwd -L)

[ "$(uname -s)" = Linux ] || skip "hiding the checkout needs Linux mount namespaces (this is $(uname -s))"
[ "$(id -u)" = 0 ] || skip "hiding the checkout needs root (unshare -m, mount); this is uid $(id -u)"
command -v unshare >/dev/null || skip "unshare(1) is missing (util-linux)"
err=$(unshare -m --propagation private true 2>&1) \
  || skip "unshare -m is not allowed here: ${err:-exit status $?}"

commit=$(git -C "$repo" rev-parse --verify -q "$rev^{commit}" 2>&1) \
  || { echo "fresh-clone: '$rev' is not a commit of $repo${commit:+: $commit}" >&2; exit 2; }

if [ -n "$(git -C "$repo" status --porcelain --untracked-files=no)" ]; then
  say "note: $repo has uncommitted changes; they are not part of the check ($rev as committed is)"
fi

tmp=
cleanup() {
  local rc=$?
  if [ -n "$tmp" ] && [ -d "$tmp" ]; then rm -rf -- "$tmp" || true; fi
  if [ "$rc" = 0 ]; then
    say "OK: the README set-up works from a fresh clone of $rev ($(elapsed) in all)"
  elif [ "$rc" = 129 ] || [ "$rc" = 130 ] || [ "$rc" = 143 ]; then
    say "stopped by a signal after $(elapsed) (exit $rc); the check is incomplete"
  elif [ "$rc" != 77 ] && [ "$rc" != 2 ]; then
    say "FAILED after $(elapsed) (exit $rc): the README set-up does not work from a fresh clone of $rev"
  fi
}
trap cleanup EXIT
trap 'exit 129' HUP
trap 'exit 130' INT
trap 'exit 143' TERM

tmp=$(mktemp -d -t pupper-fresh-clone.XXXXXX)
tmp=$(cd "$tmp" && pwd -P)
case $tmp/ in "$repo"/*)  # $TMPDIR is inside the checkout, which gets hidden: use the default
  rm -rf -- "$tmp"
  tmp=$(TMPDIR='' mktemp -d -t pupper-fresh-clone.XXXXXX)
  tmp=$(cd "$tmp" && pwd -P)
  ;;
esac
mkdir "$tmp/probe"
err=$(unshare -m --propagation private mount -t tmpfs -o size=1m tmpfs "$tmp/probe" 2>&1) \
  || skip "mounting a tmpfs in a private mount namespace is not allowed here: ${err:-exit status $?}"
rmdir "$tmp/probe"

clone=$tmp/pupper
say "clone: $rev ($(git -C "$repo" rev-parse --short "$commit")) of $repo into $clone (without ../shared)"
git clone -q --no-hardlinks --no-checkout "$repo" "$clone" || fail "git clone of $repo failed"
git -C "$clone" -c advice.detachedHead=false checkout -q --detach "$commit" \
  || fail "checking out $commit in the clone failed"
git -C "$clone" remote remove origin  # nothing in the clone may lead back here

cp -- "${BASH_SOURCE[0]}" "$tmp/check-fresh-clone.sh"
say "hide: an empty tmpfs over $repo, in a private mount namespace (unshare -m)"
spellings=("$repo")
[ "$logical" = "$repo" ] || spellings+=("$logical")
rc=0
FRESH_CLONE_T0=$t0 unshare -m --propagation private -- \
  bash "$tmp/check-fresh-clone.sh" --inside "$repo" "$tmp" "${spellings[@]:1}" || rc=$?
exit "$rc"
