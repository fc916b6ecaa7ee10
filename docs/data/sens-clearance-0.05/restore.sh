#!/bin/sh
# Put this folder's kept records back into a study folder OUT: restore.sh OUT (docs/data/restore.sh).
here=$(cd "$(dirname "$0")" && pwd)
exec sh "$here/../restore.sh" --records "$here" "$@"
