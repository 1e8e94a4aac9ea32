#!/usr/bin/env bash
# Ensure $REPO/target/peerenv is a venv holding the real MAVLink peers the
# interop tests run against, pinned, plus this repository's Python package
# python/ (fbwag-mavlink: the FBWAG dialect for pymavlink and the MAVProxy
# module `fbwag`), installed the way an integrator installs it:
#   MAVProxy 1.8.75 (mavproxy.py), pymavlink 2.4.50 (the same pin as
#   scripts/python-env.sh), mavsdk 3.17.4 (the last 3.x; its wheel ships the
#   mavsdk_server binary, 4.x does not), and `pip install ./python`.
#   executed: scripts/peer-env.sh        -> prints the venv's python path
#   sourced:  . scripts/peer-env.sh      -> sets PEER_PYTHON (no output)
# Idempotent: when every pin already imports, pip is not run for them; the
# package is reinstalled only when the content of python/ changed since it
# was installed (its hash is kept in target/peerenv/fbwag-mavlink.sha256).
# Only the package registry is used: the pins, and hatchling (the package's
# pinned build backend) in pip's isolated build environment. The build
# writes nothing into python/.
# Override the interpreter used to create the venv with PYTHON=/path/python3.
#
# Why a venv of its own: target/pyenv is the conformance reference and holds
# pymavlink and its two dependencies only. MAVProxy 1.8.75 asks for
# pymavlink>=2.4.38, which 2.4.50 satisfies (no conflict).
#
# Why --no-deps with every package listed: MAVProxy 1.8.75 requires vtk,
# opencv-python, matplotlib and quantized-mesh-tile on Linux x86_64 (1 GB
# installed), used only by its GUI modules (map3d, graphs, camera views). The
# headless router (--non-interactive/--daemon, default modules) runs without
# them; `pip check` lists exactly those four as missing. Everything else is
# pinned to the versions a full resolve chose, so the set is reproducible
# (python/README.md shows the same install for integrators).

_peerenv_pins=(
    "pymavlink==2.4.50" "lxml==6.1.3" "fastcrc==0.5.0"
    "MAVProxy==1.8.75" "pyserial==3.5" "numpy==2.4.6" "defusedxml==0.7.1"
    "pynmeagps==1.1.8" "pillow==13.0.0"
    "mavsdk==3.17.4" "grpcio==1.85.1" "protobuf==7.36.2" "typing_extensions==4.16.0"
)

_peerenv_ensure() {
    local repo venv py host
    repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd -P)" || return 1
    venv="$repo/target/peerenv"
    py="$venv/bin/python"

    _peerenv_ok() {
        # Each pinned distribution at its pinned version, and the entry
        # points the tests start.
        "$py" - "${_peerenv_pins[@]}" >/dev/null 2>&1 <<'EOF' || return 1
import sys
from importlib.metadata import version
for pin in sys.argv[1:]:
    name, want = pin.split("==")
    if version(name) != want:
        sys.exit(1)
EOF
        [ -x "$venv/bin/mavproxy.py" ] &&
            [ -x "$venv/lib/python3"*/site-packages/mavsdk/bin/mavsdk_server ]
    }

    if ! _peerenv_ok; then
        host="${PYTHON:-$(command -v python3.11 || command -v python3)}"
        if [ -z "$host" ]; then
            echo "peer-env.sh: no python3 found (set PYTHON=/path/to/python3)" >&2
            return 1
        fi
        if ! "$py" -c '' >/dev/null 2>&1; then
            if ! "$host" -m venv --clear "$venv" >&2; then
                echo "peer-env.sh: '$host -m venv $venv' failed (on Debian/Ubuntu install python3-venv)" >&2
                return 1
            fi
        fi
        if ! "$py" -m pip install --quiet --disable-pip-version-check --no-deps \
                "${_peerenv_pins[@]}" >&2; then
            echo "peer-env.sh: pip install into $venv failed" >&2
            return 1
        fi
        if ! _peerenv_ok; then
            echo "peer-env.sh: the pinned peers are still not all installed in $venv" >&2
            return 1
        fi
    fi
    _peerenv_package "$repo" "$venv" "$py" || return 1
    PEER_PYTHON="$py"
}

# (Re)install python/ when its content differs from what was installed,
# then check what it placed: the dialect modules where pymavlink's
# set_dialect looks, and MAVProxy's `module load fbwag`.
_peerenv_package() {
    local repo="$1" venv="$2" py="$3" stamp="$2/fbwag-mavlink.sha256" want
    want="$(cd "$repo" && find python -type f ! -path '*/__pycache__/*' ! -name '*.pyc' -print0 |
        LC_ALL=C sort -z | xargs -0 sha256sum | sha256sum | cut -d' ' -f1)" || return 1
    if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ] || ! _peerenv_package_ok "$py"; then
        rm -f "$stamp"
        if ! "$py" -m pip install --quiet --disable-pip-version-check --no-deps \
                --force-reinstall "$repo/python" >&2; then
            echo "peer-env.sh: pip install $repo/python into $venv failed" >&2
            return 1
        fi
        if ! _peerenv_package_ok "$py"; then
            echo "peer-env.sh: $repo/python installed, but its modules do not import from $py" >&2
            "$py" -c 'import pymavlink.dialects.v20.fbwag, MAVProxy.modules.mavproxy_fbwag' >&2
            return 1
        fi
        printf '%s\n' "$want" >"$stamp"
    fi
}

_peerenv_package_ok() {
    "$1" - >/dev/null 2>&1 <<'EOF'
import pymavlink.dialects.v10.fbwag as v10
import pymavlink.dialects.v20.fbwag as v20
import MAVProxy.modules.mavproxy_fbwag as module
assert v20.MAVLink_fbwag_notice_message.crc_extra == 30
assert hasattr(v10, "MAVLink_heartbeat_message")
assert callable(module.init)
EOF
}

if [ "${BASH_SOURCE[0]}" = "$0" ]; then
    _peerenv_ensure || exit 1
    printf '%s\n' "$PEER_PYTHON"
else
    _peerenv_ensure
    _peerenv_rc=$?
    unset -f _peerenv_ensure _peerenv_ok _peerenv_package _peerenv_package_ok
    unset _peerenv_pins
    [ "$_peerenv_rc" -eq 0 ] && export PEER_PYTHON
    return "$_peerenv_rc" 2>/dev/null || true
fi
