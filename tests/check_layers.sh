#!/usr/bin/env bash
# The renderer's layer rule (make lint-c): renderer/src/ holds one folder per
# layer, lowest first as in LAYERS; a file includes headers of its own layer
# and of the layers below it, always by their layer-qualified name
# ("base/vec.h"), never a header of a layer above. Each third-party library
# is included by one layer only, so that the rest of the code never sees it.
#
# usage: tests/check_layers.sh [SRC_DIR]   (default renderer/src)
set -euo pipefail
src="${1:-renderer/src}"
layers=(base geometry config scene sampling render cli)
declare -A rank
for i in "${!layers[@]}"; do rank[${layers[$i]}]=$i; done
# library header prefix -> the one layer that may include it
declare -A owner=([yaml.h]=config [assimp/]=config [zlib.h]=config [embree3/]=scene [OpenEXR/]=render)

bad=0
report() { echo "check_layers: $*" >&2; bad=1; }

for f in "$src"/*; do
    name="$(basename "$f")"
    if [ -f "$f" ] && [ "$name" != README.md ]; then report "$f: a file outside the layer folders"; fi
    if [ -d "$f" ] && [ -z "${rank[$name]+x}" ]; then report "$f: a folder that is not a layer (${layers[*]})"; fi
done

n=0
for layer in "${layers[@]}"; do
    [ -d "$src/$layer" ] || { report "$src/$layer: missing layer folder"; continue; }
    for f in "$src/$layer"/*.[ch]; do
        [ -e "$f" ] || continue
        n=$((n + 1))
        while IFS=: read -r line text; do
            inc="$(sed -E 's/^#include "([^"]*)".*/\1/' <<<"$text")"
            dep="${inc%%/*}"
            if [ "$dep" = "$inc" ]; then
                report "$f:$line: \"$inc\" does not name its layer (write \"LAYER/$inc\")"
            elif [ -z "${rank[$dep]+x}" ]; then
                report "$f:$line: \"$inc\" is in no layer"
            elif [ "${rank[$dep]}" -gt "${rank[$layer]}" ]; then
                report "$f:$line: $layer includes \"$inc\" of the layer above it, $dep"
            elif [ ! -f "$src/$inc" ]; then
                report "$f:$line: \"$inc\" does not exist"
            fi
        done < <(grep -n '^#include "' "$f" || true)
        while IFS=: read -r line text; do
            for lib in "${!owner[@]}"; do
                if [[ "$text" == "#include <$lib"* ]] && [ "${owner[$lib]}" != "$layer" ]; then
                    report "$f:$line: <$lib...> belongs to the ${owner[$lib]} layer only"
                fi
            done
        done < <(grep -n '^#include <' "$f" || true)
    done
done
[ "$bad" -eq 0 ] || exit 1
echo "check_layers: $n files in ${#layers[@]} layers, no include points up"
