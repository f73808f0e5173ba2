#!/usr/bin/env bash
# Set up the Python environments and run the demo.
#
#   bash scripts/setup.sh            # .venv (bpy 5.0.1) + .venv45 (bpy 4.5 LTS), then the demo
#   bash scripts/setup.sh --no-demo  # environments only (used by scripts/test.sh)
#
# Idempotent: each venv keeps a stamp with the hash of its requirements file and Python
# version; when it matches, nothing is installed (a re-run takes well under a second).
# Needs Python 3.11 (bpy 5.0.1 and 4.5.15 ship cp311 wheels); override with PYTHON=/path/to/python.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

RUN_DEMO=1
for arg in "$@"; do
    case "$arg" in
        --no-demo) RUN_DEMO=0 ;;
        -h|--help) sed -n '2,10p' "$0"; exit 0 ;;
        *) echo "setup.sh: unknown argument: $arg (expected --no-demo)" >&2; exit 2 ;;
    esac
done

pick_python() {
    if [[ -n "${PYTHON:-}" ]]; then echo "$PYTHON"; return; fi
    for cand in python3.11 python3; do
        if command -v "$cand" >/dev/null 2>&1; then command -v "$cand"; return; fi
    done
    echo "setup.sh: no python3.11 or python3 found" >&2
    exit 1
}

# ensure_venv DIR REQUIREMENTS
ensure_venv() {
    local venv="$1" req="$2" py stamp want have
    stamp="$venv/.requirements.stamp"
    if [[ -x "$venv/bin/python" ]] && ! "$venv/bin/python" -c 'import sys' >/dev/null 2>&1; then
        echo "setup.sh: $venv is broken, re-creating it"
        rm -rf "$venv"
    fi
    if [[ ! -x "$venv/bin/python" ]]; then
        py="$(pick_python)"
        local ver
        ver="$("$py" -c 'import sys; print("%d.%d" % sys.version_info[:2])')"
        if [[ "$ver" != "3.11" ]]; then
            echo "setup.sh: warning: $py is Python $ver; bpy==5.0.1/4.5.15 need Python 3.11" >&2
        fi
        echo "setup.sh: creating $venv with $py ($ver)"
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
    echo "setup.sh: installing $req into $venv (bpy is ~350 MB; about a minute)"
    rm -f "$stamp"
    "$venv/bin/python" -m pip install --disable-pip-version-check -q -r "$req"
    echo "$want" > "$stamp"
}

ensure_venv .venv requirements.txt
ensure_venv .venv45 requirements-45.txt

if [[ "$RUN_DEMO" == 1 ]]; then
    .venv/bin/python scripts/demo.py
fi
