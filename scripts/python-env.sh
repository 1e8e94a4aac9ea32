#!/usr/bin/env bash
# Ensure $REPO/target/pyenv is a venv holding exactly pymavlink==2.4.50, the
# reference implementation our conformance tests and benchmarks compare with.
#   executed: scripts/python-env.sh        -> prints the venv's python path
#   sourced:  . scripts/python-env.sh      -> sets PYMAVLINK_PYTHON (no output)
# Idempotent: when the pinned version already imports, pip is not run at all.
# Override the interpreter used to create the venv with PYTHON=/path/python3.

_pyenv_ensure() {
    local want="2.4.50" repo venv py host
    # Derive the repo from this file's location so any cwd works.
    repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd -P)" || return 1
    venv="$repo/target/pyenv"
    py="$venv/bin/python"

    _pyenv_ok() {
        "$py" -c "import sys, pymavlink.generator.mavparse, pymavlink
sys.exit(pymavlink.__version__ != '$want')" >/dev/null 2>&1
    }

    if ! _pyenv_ok; then
        host="${PYTHON:-$(command -v python3.11 || command -v python3)}"
        if [ -z "$host" ]; then
            echo "python-env.sh: no python3 found (set PYTHON=/path/to/python3)" >&2
            return 1
        fi
        # A venv whose interpreter no longer runs (moved repo, upgraded host
        # python) is recreated rather than patched.
        if ! "$py" -c '' >/dev/null 2>&1; then
            if ! "$host" -m venv --clear "$venv" >&2; then
                echo "python-env.sh: '$host -m venv $venv' failed (on Debian/Ubuntu install python3-venv)" >&2
                return 1
            fi
        fi
        # pip's own output goes to stderr: stdout carries only the path.
        if ! "$py" -m pip install --quiet --disable-pip-version-check \
                "pymavlink==$want" >&2; then
            echo "python-env.sh: pip install pymavlink==$want into $venv failed" >&2
            return 1
        fi
        if ! _pyenv_ok; then
            echo "python-env.sh: pymavlink $want still not importable from $py" >&2
            return 1
        fi
    fi
    PYMAVLINK_PYTHON="$py"
}

if [ "${BASH_SOURCE[0]}" = "$0" ]; then
    # Executed: fail with the function's status, print the path on success.
    _pyenv_ensure || exit 1
    printf '%s\n' "$PYMAVLINK_PYTHON"
else
    # Sourced: never exit the caller's shell; leave no helper functions behind.
    _pyenv_ensure
    _pyenv_rc=$?
    unset -f _pyenv_ensure _pyenv_ok
    [ "$_pyenv_rc" -eq 0 ] && export PYMAVLINK_PYTHON
    return "$_pyenv_rc" 2>/dev/null || true
fi
