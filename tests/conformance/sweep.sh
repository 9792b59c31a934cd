#!/usr/bin/env bash
# Compiles and runs every shader of third-party collections, kept out of this repository, and
# sums up what fails, by diagnostic code: how rtsl is judged against shaders nobody here wrote.
#
#   bash tests/conformance/sweep.sh [RTSL] DIR...
#
# DIR: folders of `.sl` files, e.g. checkouts of the RenderMan Repository, Aqsis's `shaders/` and
# `examples/`, or a book's shaders. Each shader is compiled in its own folder with every folder
# of the sweep that holds headers (`.h`, `.slh`, `.sl` files no shader defines) on the include
# path, as their makefiles do; each one that compiles is run with `rtsl shade` (a 256 x 256 grid,
# `SHADE_TIMEOUT` seconds, 60 by default). Per-file results go to `SWEEP_LOG` (default
# /tmp/rtsl-sweep.log); the summary to stdout. Exit status 0: the sweep ran, whatever it found.
set -u
RTSL=target/release/rtsl
if [ $# -gt 0 ] && [ -x "$1" ] && [ ! -d "$1" ]; then RTSL=$1; shift; fi
[ $# -gt 0 ] || { echo "usage: $0 [RTSL] DIR..." >&2; exit 2; }
[ -x "$RTSL" ] || { echo "no rtsl binary at $RTSL (cargo build --release)" >&2; exit 2; }
RTSL=$(realpath "$RTSL")
LOG=${SWEEP_LOG:-/tmp/rtsl-sweep.log}
TIMEOUT=${SHADE_TIMEOUT:-60}
: > "$LOG"
includes=()
while IFS= read -r d; do includes+=(-I "$d"); done < <(
    find "$@" \( -name '*.h' -o -name '*.slh' -o -name '*.sl' \) -printf '%h\n' | xargs -r realpath | sort -u)
total=0; compiled=0; shaded=0
while IFS= read -r f; do
    total=$((total + 1))
    dir=$(dirname "$f"); base=$(basename "$f")
    if ! out=$(cd "$dir" && timeout 60 "$RTSL" --color never compile "${includes[@]}" "$base" 2>&1); then
        printf '== %s: compile\n%s\n' "$f" "$(grep -E '^error' <<<"$out" | head -3)" >> "$LOG"
        continue
    fi
    compiled=$((compiled + 1))
    if out=$(cd "$dir" && timeout "$TIMEOUT" "$RTSL" --color never shade "${includes[@]}" "$base" \
            -o "/tmp/rtsl-sweep-$$.png" 2>&1); then
        shaded=$((shaded + 1))
    else
        rc=$?
        printf '== %s: shade (exit %s)\n%s\n' "$f" "$rc" "$(grep -E '^error' <<<"$out" | head -3)" >> "$LOG"
    fi
done < <(find "$@" -name '*.sl' | sort)
rm -f "/tmp/rtsl-sweep-$$.png"
echo "shaders: $total, compiled: $compiled, shaded: $shaded (details: $LOG)"
echo "first errors, by kind:"
grep -E '^error' "$LOG" | sed -E 's/`[^`]*`/`X`/g; s/^error: [^:]*: /error: /' | sort | uniq -c | sort -rn | head -20
