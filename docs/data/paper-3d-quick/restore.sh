#!/bin/sh
# Put the kept records of the quick 3D study back into a study folder OUT (created if missing):
# OUT/study.toml and OUT/points/<design key>/ for each finished point. Then
#   hydrojam reproduce --dimension 3 --quick -o OUT --report-only [--compare-2d OUT2D]
# writes its report from them in seconds. Usage: restore.sh OUT
set -eu
[ $# -eq 1 ] || { echo "usage: $0 OUT" >&2; exit 2; }
here=$(cd "$(dirname "$0")" && pwd)
out=$1
if [ -e "$out/study.toml" ]; then  # the same study (resumed): keep its file; another: refuse
    grep -q '^name = "paper-3d-quick"$' "$out/study.toml" || {
        echo "$out/study.toml: holds another study, not paper-3d-quick; choose another folder" >&2
        exit 2
    }
else
    mkdir -p "$out"
    cp "$here/study.toml" "$out/study.toml"
fi
n=0
for rec in "$here"/*/; do
    [ -d "$rec" ] || continue  # no record kept yet
    n=$((n + 1))
    key=$(basename "$rec")
    key=${key#*-}
    mkdir -p "$out/points/$key"
    cp "$rec"* "$out/points/$key/"
done
echo "restored $n points into $out"
