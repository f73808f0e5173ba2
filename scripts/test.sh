#!/usr/bin/env bash
# Run every test: all of tests/ with bpy 5.0.1, then tests/blender again with bpy 4.5 LTS.
#
#   bash scripts/test.sh                 # everything
#   bash scripts/test.sh -k furnace -x   # extra arguments go to both pytest runs
#
# Exits non-zero if either run fails.  Blender tests never skip here (HAZY_GLOSS_REQUIRE_BPY=1
# turns a missing bpy into an error).
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

# run LABEL PYTHON PATHS... -- EXTRA_ARGS...
run() {
    local label="$1" py="$2" log="$LOG_DIR/$3.log" start end rc summary verdict
    local target="$4"
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

run "bpy $(.venv/bin/python -c 'import importlib.metadata as m; print(m.version("bpy"))') (tests/)" \
    .venv/bin/python main tests "$@"
run "bpy $(.venv45/bin/python -c 'import importlib.metadata as m; print(m.version("bpy"))') (tests/blender)" \
    .venv45/bin/python lts tests/blender "$@"

echo
echo "=== summary ==="
for line in "${SUMMARIES[@]}"; do echo "$line"; done
exit $STATUS
