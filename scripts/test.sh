#!/usr/bin/env bash
# Run every test: the pure (bpy-free) tests once, then the Blender tests under each supported
# Blender: 5.3 (.venv), 5.2 LTS (.venv52) and 4.5 LTS (.venv45).
#
#   bash scripts/test.sh                 # everything
#   bash scripts/test.sh -k furnace -x   # extra arguments go to every pytest run
#
# Exits non-zero if any run fails.  Blender tests never skip here (HAZY_GLOSS_REQUIRE_BPY=1
# turns a missing bpy into an error); the add-on's own DeprecationWarnings are errors there
# (tests/blender/conftest.py).
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

bash scripts/setup.sh --no-demo || { echo "test.sh: setup failed" >&2; exit 1; }

export HAZY_GLOSS_REQUIRE_BPY=1
export PYTHONDONTWRITEBYTECODE=1
LOG_DIR="$(mktemp -d -t hazy_gloss_test.XXXXXX)"
trap 'rm -rf "$LOG_DIR"' EXIT

SUMMARIES=()
STATUS=0
T0=$(date +%s)

# run LABEL PYTHON LOGNAME TARGET EXTRA_ARGS...
run() {
    local label="$1" py="$2" log="$LOG_DIR/$3.log" target="$4" start end rc summary verdict
    shift 4
    echo
    echo "=== $label: $py -m pytest $target -q $* ==="
    start=$(date +%s)
    "$py" -m pytest "$target" -q "$@" 2>&1 | tee "$log"
    rc=${PIPESTATUS[0]}
    end=$(date +%s)
    summary="$(grep -E '^(=+ )?[0-9]+ (passed|failed|error|errors|skipped|deselected)|no tests ran' "$log" | tail -n 1 | sed -E 's/^=+ //; s/ =+$//')"
    if [[ $rc -eq 0 ]]; then
        verdict="PASS"
    elif [[ $rc -eq 5 && $# -gt 0 ]]; then
        verdict="PASS (no tests selected)"  # e.g. -k matched only pure tests
        rc=0
    else
        verdict="FAIL (pytest exit $rc)"
        STATUS=1
    fi
    SUMMARIES+=("$label: $verdict - ${summary:-no summary} [wall $((end - start)) s]")
}

bpy_version() {
    "$1" -c 'import importlib.metadata as m; print(m.version("bpy"))'
}

run "pure (no bpy)" .venv/bin/python pure tests/pure "$@"
run "bpy $(bpy_version .venv/bin/python) (tests/blender)" .venv/bin/python b53 tests/blender "$@"
run "bpy $(bpy_version .venv52/bin/python) LTS (tests/blender)" .venv52/bin/python b52 tests/blender "$@"
run "bpy $(bpy_version .venv45/bin/python) LTS (tests/blender)" .venv45/bin/python b45 tests/blender "$@"

echo
echo "=== summary (total wall $(( $(date +%s) - T0 )) s) ==="
for line in "${SUMMARIES[@]}"; do echo "$line"; done
exit $STATUS
