#!/usr/bin/env bash
# Renders third-party RIB files that come with the image another renderer made of them, and
# compares: how far rtsl's picture is from BMRT's or PRMan's, scene by scene.
#
#   bash tests/conformance/references.sh [RTSL] DIR...
#
# DIR: folders searched for `.rib` files (e.g. a checkout of the RenderMan Repository). A file
# counts when its first `Display` names an image that exists beside it (`.tif`, `.tiff`): the
# reference. It is rendered in its own folder (as RenderMan does, rtsl writes a RIB file's
# values as rendered and reads its 8-bit textures as stored), every folder of the sweep
# that holds shaders on `-S`, every folder that holds headers on `-I`, `--keep-going`, at the
# file's own `Format`. Prints, per file, the mean and 90th percentile of the absolute difference
# per channel in 8-bit codes, and the warnings rtsl gave. Needs python3 with Pillow and NumPy.
# Images go to `REFERENCES_OUT` (default /tmp/rtsl-references): NAME.png, and NAME_cmp.png with
# the reference on the left.
set -u
RTSL=target/release/rtsl
if [ $# -gt 0 ] && [ -x "$1" ] && [ ! -d "$1" ]; then RTSL=$1; shift; fi
[ $# -gt 0 ] || { echo "usage: $0 [RTSL] DIR..." >&2; exit 2; }
[ -x "$RTSL" ] || { echo "no rtsl binary at $RTSL (cargo build --release)" >&2; exit 2; }
python3 -c 'import PIL, numpy' 2>/dev/null || { echo "needs python3 with Pillow and NumPy" >&2; exit 2; }
RTSL=$(realpath "$RTSL")
OUT=${REFERENCES_OUT:-/tmp/rtsl-references}
mkdir -p "$OUT"
shaders=$(find "$@" -name '*.sl' -printf '%h\n' | xargs -r realpath | sort -u | paste -sd:)
includes=()
while IFS= read -r d; do includes+=(-I "$d"); done < <(
    find "$@" \( -name '*.h' -o -name '*.slh' -o -name '*.sl' \) -printf '%h\n' | xargs -r realpath | sort -u)
while IFS= read -r rib; do
    dir=$(dirname "$rib")
    ref=$(grep -m1 -aE '^[[:space:]]*Display' "$rib" | awk '{print $2}' | tr -d '"')
    [ -n "$ref" ] && [ -f "$dir/$ref" ] || continue
    name=$(basename "$rib" .rib)
    log=$(cd "$dir" && timeout 300 "$RTSL" --color never render --keep-going -S ".:$shaders" \
        "${includes[@]}" -o "$OUT/$name.png" "$(basename "$rib")" 2>&1)
    warnings=$(grep -E '^(warning|error)' <<<"$log" | grep -v 'parts\? of the scene missing' | sort | uniq -c |
        awk '{$1=$1; print}' | paste -sd';')
    python3 - "$dir/$ref" "$OUT/$name.png" "$OUT/${name}_cmp.png" "$name" "$warnings" <<'EOF'
import sys
import numpy as np
from PIL import Image
ref_path, out_path, cmp_path, name, warnings = sys.argv[1:]
try:
    ref = Image.open(ref_path).convert('RGB')
    out = Image.open(out_path).convert('RGB')
except Exception as e:  # a reference in a format Pillow cannot read, or no image rendered
    print(f'{name:28} not compared: {e}')
    sys.exit(0)
if out.size != ref.size:
    out = out.resize(ref.size)
d = np.abs(np.asarray(ref, dtype=float) - np.asarray(out, dtype=float))
print(f'{name:28} mean {d.mean():5.1f}  p90 {np.percentile(d, 90):5.0f}  {warnings}')
w, h = ref.size
sheet = Image.new('RGB', (2 * w + 4, h), (255, 0, 255))
sheet.paste(ref, (0, 0))
sheet.paste(out, (w + 4, 0))
sheet.save(cmp_path)
EOF
done < <(find "$@" -name '*.rib' | sort)
