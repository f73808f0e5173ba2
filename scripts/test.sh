#!/usr/bin/env bash
# Run every test: the pure (bpy-free) tests once and the Blender tests under each supported
# Blender: 5.3 (.venv), 5.2 LTS (.venv52) and 4.5 LTS (.venv45), two suites at a time (each
# suite's output is printed whole when it ends; HAZY_GLOSS_TEST_JOBS=1: one at a time).
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

STATUS=0
T0=$(date +%s)
#: suites run side by side (the machine's cores; Blender's Python work is single-threaded, so two
#: suites on two cores take about the time of one): HAZY_GLOSS_TEST_JOBS=1 runs them in turn
JOBS="${HAZY_GLOSS_TEST_JOBS:-$(nproc 2>/dev/null || echo 2)}"
(( JOBS > 2 )) && JOBS=2

bpy_version() {
    "$1" -c 'import importlib.metadata as m; print(m.version("bpy"))'
}

# LABEL|PYTHON|LOGNAME|TARGET, longest first
SUITES=(
    "bpy $(bpy_version .venv/bin/python) (tests/blender)|.venv/bin/python|b53|tests/blender"
    "bpy $(bpy_version .venv52/bin/python) LTS (tests/blender)|.venv52/bin/python|b52|tests/blender"
    "bpy $(bpy_version .venv45/bin/python) LTS (tests/blender)|.venv45/bin/python|b45|tests/blender"
    "pure (no bpy)|.venv/bin/python|pure|tests/pure"
)

# one suite in the background: its output to its log, then rc and wall seconds beside it
start_suite() {
    local label py name target
    IFS='|' read -r label py name target <<< "$1"
    shift
    echo "=== started: $label: $py -m pytest $target -q $* ==="
    ( s=$(date +%s); "$py" -m pytest "$target" -q "$@" > "$LOG_DIR/$name.log" 2>&1
      echo "$? $(( $(date +%s) - s ))" > "$LOG_DIR/$name.rc" ) &
}

running=()
for suite in "${SUITES[@]}"; do
    while (( ${#running[@]} >= JOBS )); do
        wait -n 2>/dev/null || true
        still=()
        for p in "${running[@]}"; do kill -0 "$p" 2>/dev/null && still+=("$p"); done
        running=("${still[@]}")
    done
    start_suite "$suite" "$@"
    running+=($!)
done
wait

SUMMARIES=()
for suite in "${SUITES[@]}"; do
    IFS='|' read -r label py name target <<< "$suite"
    echo
    echo "=== $label: $py -m pytest $target -q $* ==="
    cat "$LOG_DIR/$name.log"
    read -r rc secs < "$LOG_DIR/$name.rc"
    summary="$(grep -E '^(=+ )?[0-9]+ (passed|failed|error|errors|skipped|deselected)|no tests ran' "$LOG_DIR/$name.log" | tail -n 1 | sed -E 's/^=+ //; s/ =+$//')"
    if [[ $rc -eq 0 ]]; then
        verdict="PASS"
    elif [[ $rc -eq 5 && $# -gt 0 ]]; then
        verdict="PASS (no tests selected)"  # e.g. -k matched only pure tests
    else
        verdict="FAIL (pytest exit $rc)"
        STATUS=1
    fi
    SUMMARIES+=("$label: $verdict - ${summary:-no summary} [wall $secs s]")
done

echo
echo "=== summary (total wall $(( $(date +%s) - T0 )) s) ==="
for line in "${SUMMARIES[@]}"; do echo "$line"; done
exit $STATUS
