#!/bin/sh
# Put the kept records of a study (the folder this file is in, written by docs/data/keep.py) back
# into a study folder OUT (created if missing): OUT/study.toml and OUT/points/<design key>/ for each
# finished point. Then the study's command with --report-only (e.g.
#   hydrojam reproduce --dimension 3 --quick --replicas 3 -o OUT --report-only [--compare-2d OUT2D])
# writes its report from them in seconds, and without it runs the points not kept.
# Usage: docs/data/STUDY/restore.sh OUT (each records folder's restore.sh calls this one with
# --records, its own folder), or docs/data/restore.sh --records docs/data/STUDY OUT.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
if [ "${1:-}" = "--records" ] && [ $# -ge 2 ]; then here=$(cd "$2" && pwd); shift 2; fi
[ $# -eq 1 ] || { echo "usage: $0 [--records DIR] OUT" >&2; exit 2; }
out=$1
[ -f "$here/study.toml" ] || { echo "$here: no study.toml; run the restore.sh in a study's records folder" >&2; exit 2; }
name=$(sed -n 's/^name = "\(.*\)"$/\1/p' "$here/study.toml" | head -n 1)
if [ -e "$out/study.toml" ]; then  # the same study (resumed): keep its file; another: refuse
    grep -qxF "name = \"$name\"" "$out/study.toml" || {
        echo "$out/study.toml: holds another study, not $name; choose another folder" >&2
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
