#!/usr/bin/env bash
# Create the virtual environment (if missing), install hydrojam with its test and docs extras, and make sure
# gmsh can load: its wheel needs system GL/X libraries that a bare machine may lack.
set -euo pipefail
venv=${1:-.venv}
python=${PYTHON:-python3}
[ -x "$venv/bin/python" ] || "$python" -m venv "$venv"
"$venv/bin/python" -m pip install -q --disable-pip-version-check -e '.[test,docs]'
if ! "$venv/bin/python" -c 'import gmsh' >/dev/null 2>&1; then
    echo "bootstrap: gmsh cannot load its system libraries; installing them with apt-get" >&2
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq libglu1-mesa libxcursor1 libxft2 libxinerama1 libxrender1 libgl1 >/dev/null
    "$venv/bin/python" -c 'import gmsh'
fi
