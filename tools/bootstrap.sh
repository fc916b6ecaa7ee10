#!/usr/bin/env bash
# Create the virtual environment (if missing), install hydrojam with its test, docs and render extras, and
# make sure gmsh and VTK can load: their wheels need system GL/X libraries that a bare machine may lack
# (VTK renders off-screen through EGL or OSMesa where there is no display).
set -euo pipefail
venv=${1:-.venv}
python=${PYTHON:-python3}
[ -x "$venv/bin/python" ] || "$python" -m venv "$venv"
"$venv/bin/python" -m pip install -q --disable-pip-version-check -e '.[test,docs,render]'
apt_install() {
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq "$@" >/dev/null
}
if ! "$venv/bin/python" -c 'import gmsh' >/dev/null 2>&1; then
    echo "bootstrap: gmsh cannot load its system libraries; installing them with apt-get" >&2
    apt_install libglu1-mesa libxcursor1 libxft2 libxinerama1 libxrender1 libgl1
    "$venv/bin/python" -c 'import gmsh'
fi
render_check='from hydrojam.actuator.render import render_check; render_check()'
if ! "$venv/bin/python" -c "$render_check" >/dev/null 2>&1; then
    echo "bootstrap: VTK cannot render off-screen; installing EGL and OSMesa with apt-get" >&2
    apt_install libegl1 libegl-mesa0 libgbm1 libgl1-mesa-dri libosmesa6 libgl1 libxrender1
    "$venv/bin/python" -c "$render_check"
fi
