#!/usr/bin/env bash
# Ensure $REPO/target/peerenv is a venv holding the real MAVLink peers the
# interop tests run against, pinned, plus the FBWAG dialect and MAVProxy
# module installed into them (interop/install_dialect.py):
#   MAVProxy 1.8.75 (mavproxy.py), pymavlink 2.4.50 (the same pin as
#   scripts/python-env.sh), mavsdk 3.17.4 (the last 3.x; its wheel ships the
#   mavsdk_server binary, 4.x does not).
#   executed: scripts/peer-env.sh        -> prints the venv's python path
#   sourced:  . scripts/peer-env.sh      -> sets PEER_PYTHON (no output)
# Idempotent: when every pin already imports, pip is not run at all (the
# dialect step still runs: it rewrites nothing that is up to date).
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
# pinned to the versions a full resolve chose, so the set is reproducible.

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
    if ! "$py" "$repo/interop/install_dialect.py" --quiet >&2; then
        echo "peer-env.sh: installing the FBWAG dialect into $venv failed" >&2
        return 1
    fi
    PEER_PYTHON="$py"
}

if [ "${BASH_SOURCE[0]}" = "$0" ]; then
    _peerenv_ensure || exit 1
    printf '%s\n' "$PEER_PYTHON"
else
    _peerenv_ensure
    _peerenv_rc=$?
    unset -f _peerenv_ensure _peerenv_ok
    unset _peerenv_pins
    [ "$_peerenv_rc" -eq 0 ] && export PEER_PYTHON
    return "$_peerenv_rc" 2>/dev/null || true
fi
