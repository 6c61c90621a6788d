# Sourced by the install scripts: `ensure_venv NAME VENV IMPORTS PIN...` makes the virtual
# environment VENV with the pinned packages unless its stamp file already records the same
# pins and it imports IMPORTS (a Python import list, e.g. "mujoco, numpy"); finds python3
# (or $PYTHON) and installs Debian's python3-venv when the venv module is missing. NAME
# prefixes the messages. Run from the repository root.

ensure_venv() {
    local name="$1" venv="$2" imports="$3"
    shift 3
    local want="$*"
    local stamp="$venv/legwork-stamp"
    if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && [ -x "$venv/bin/python" ] \
        && "$venv/bin/python" -c "import $imports" >/dev/null 2>&1; then
        echo "$name: $venv already has $want"
        return 0
    fi
    local python="${PYTHON:-}"
    if [ -z "$python" ]; then
        for candidate in python3 python; do
            if command -v "$candidate" >/dev/null 2>&1; then python="$candidate"; break; fi
        done
    fi
    if [ -z "$python" ]; then
        echo "$name: no python3 on PATH; install Python 3.10+ (with venv) first" >&2
        return 1
    fi
    if ! "$python" -c "import venv, ensurepip" >/dev/null 2>&1; then
        # Debian splits venv/ensurepip off python3 into python3-venv.
        if command -v apt-get >/dev/null 2>&1; then
            SUDO=()
            if [ "$(id -u)" -ne 0 ]; then SUDO=(sudo); fi
            echo "$name: $python has no venv module; installing python3-venv with apt-get"
            source scripts/apt-wait.sh
            apt_get update -q
            apt_get install -y -q --no-install-recommends python3-venv
        else
            echo "$name: $python has no venv module and apt-get is not available" >&2
            return 1
        fi
    fi
    echo "$name: creating $venv with $want"
    rm -rf "$venv"
    "$python" -m venv "$venv"
    "$venv/bin/python" -m pip install -q --disable-pip-version-check "$@"
    "$venv/bin/python" -c "import $imports" || return 1
    echo "$want" > "$stamp"
}
