#!/usr/bin/env bash
# Set up the Python environments and run the main job (the demo gallery, Blender 5.3).
#
#   bash scripts/setup.sh            # .venv (bpy 5.3), .venv52 (bpy 5.2 LTS), .venv45 (bpy 4.5 LTS), demo
#   bash scripts/setup.sh --no-demo  # environments only (used by scripts/test.sh)
#
# bpy 5.3.0 and 5.2.3 ship wheels for Python 3.13 only, bpy 4.5.15 for Python 3.11 only.  Each
# interpreter is looked for on PATH (python3.13 / python3.11) and in pyenv's versions; override
# with PYTHON313=/path/to/python3.13 and PYTHON311=/path/to/python3.11.
# Idempotent: each venv keeps a stamp with the hash of its requirements file and Python version;
# when it matches, nothing is installed (a re-run takes about a second).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

RUN_DEMO=1
for arg in "$@"; do
    case "$arg" in
        --no-demo) RUN_DEMO=0 ;;
        -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
        *) echo "setup.sh: unknown argument: $arg (expected --no-demo)" >&2; exit 2 ;;
    esac
done

# find_python X.Y: print the path of a Python X.Y interpreter, or nothing.
find_python() {
    local want="$1" override cand root
    override="PYTHON${want/./}"
    if [[ -n "${!override:-}" ]]; then
        if [[ "$("${!override}" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null)" == "$want" ]]; then
            echo "${!override}"
        else
            echo "setup.sh: $override=${!override} is not a Python $want interpreter" >&2
        fi
        return
    fi
    for cand in "python$want" python3; do
        if command -v "$cand" >/dev/null 2>&1 && [[ "$("$cand" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null)" == "$want" ]]; then
            command -v "$cand"
            return
        fi
    done
    root="$(pyenv root 2>/dev/null || echo "${PYENV_ROOT:-$HOME/.pyenv}")"
    for cand in $(ls -d "$root"/versions/"$want".*/bin/python"$want" 2>/dev/null | sort -V -r); do
        if [[ -x "$cand" ]]; then
            echo "$cand"
            return
        fi
    done
}

need_python() {
    local want="$1" what="$2" py
    py="$(find_python "$want")"
    if [[ -z "$py" ]]; then
        {
            echo "setup.sh: Python $want not found; $what needs it."
            echo "  Install it (pyenv install $want, or your system's python$want and python$want-venv"
            echo "  packages), or point PYTHON${want/./}=/path/to/python$want at one."
        } >&2
        exit 1
    fi
    echo "$py"
}

# ensure_venv DIR REQUIREMENTS PYTHON_VERSION WHAT
ensure_venv() {
    local venv="$1" req="$2" want_ver="$3" what="$4" py stamp want have ver
    stamp="$venv/.requirements.stamp"
    if [[ -x "$venv/bin/python" ]]; then
        ver="$("$venv/bin/python" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null || true)"
        if [[ "$ver" != "$want_ver" ]]; then
            echo "setup.sh: $venv has Python ${ver:-(broken)}, $what needs $want_ver: re-creating it"
            rm -rf "$venv"
        fi
    fi
    if [[ ! -x "$venv/bin/python" ]]; then
        py="$(need_python "$want_ver" "$what")"
        echo "setup.sh: creating $venv with $py"
        "$py" -m venv "$venv"
    fi
    want="$("$venv/bin/python" - "$req" <<'PY'
import hashlib, sys
data = open(sys.argv[1], "rb").read() + sys.version.encode()
print(hashlib.sha256(data).hexdigest())
PY
)"
    have="$(cat "$stamp" 2>/dev/null || true)"
    if [[ "$want" == "$have" ]]; then
        echo "setup.sh: $venv up to date ($req)"
        return 0
    fi
    echo "setup.sh: installing $req into $venv ($what; bpy is ~400 MB: about a minute)"
    rm -f "$stamp"
    "$venv/bin/python" -m pip install --disable-pip-version-check -q -r "$req"
    echo "$want" > "$stamp"
}

ensure_venv .venv requirements.txt 3.13 "Blender 5.3 (bpy 5.3.0)"
ensure_venv .venv52 requirements-52.txt 3.13 "Blender 5.2 LTS (bpy 5.2.3)"
ensure_venv .venv45 requirements-45.txt 3.11 "Blender 4.5 LTS (bpy 4.5.15)"

if [[ "$RUN_DEMO" == 1 ]]; then
    .venv/bin/python scripts/demo.py
fi
