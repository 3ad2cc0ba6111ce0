#!/usr/bin/env bash
# The seed table: every shipped robot mission in each world it is shipped for, run on seeds
# FIRST..LAST with the release binary; prints mission, world, successes, collisions (total, and
# runs with any) and the median simulated duration of the runs.
#
#   cargo build --release --bin marie && missions/seed-table.sh [FIRST [LAST]]   # default 1 100
#
# Needs bash and jq. MARIE overrides the binary (default target/release/marie, or
# $CARGO_TARGET_DIR/release/marie). Run from anywhere: paths are relative to the repository.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
first=${1:-1}
last=${2:-100}
marie=${MARIE:-${CARGO_TARGET_DIR:-$root/target}/release/marie}
[ -x "$marie" ] || { echo "no binary at $marie: cargo build --release --bin marie" >&2; exit 2; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# mission file, world file (the mission's own world)
pairs=(
    "missions/docking.toml missions/worlds/lab.toml"
    "missions/docking-corridor.toml missions/worlds/corridor.toml"
    "missions/docking-lshape.toml missions/worlds/lshape.toml"
    "missions/corner.toml missions/worlds/corner.toml"
    "missions/docking-recover.toml missions/worlds/deadend.toml"
    "missions/docking-recover.toml missions/worlds/lab.toml"
    "missions/docking.toml missions/worlds/deadend.toml"
)

printf '%-32s %-10s %9s %10s %9s  %s\n' mission world successes collisions median_s failed_seeds
for pair in "${pairs[@]}"; do
    read -r mission world <<<"$pair"
    ok=0 hits=0 hit_runs=0 runs=0 failed=()
    durations=()
    for seed in $(seq "$first" "$last"); do
        report="$tmp/r.json"
        rm -f "$report"
        "$marie" run "$root/$mission" --world "$root/$world" --seed "$seed" --report "$report" \
            >/dev/null 2>&1 || true
        runs=$((runs + 1))
        if [ ! -s "$report" ]; then
            failed+=("$seed")
            continue
        fi
        read -r outcome collisions duration < <(jq -r \
            '[.outcome, (.collisions // 0), (.duration_ms // 0)] | @tsv' "$report")
        durations+=("$duration")
        hits=$((hits + collisions))
        [ "$collisions" -gt 0 ] && hit_runs=$((hit_runs + 1))
        if [ "$outcome" = succeeded ] && [ "$collisions" -eq 0 ]; then
            ok=$((ok + 1))
        else
            failed+=("$seed")
        fi
    done
    median=$(printf '%s\n' "${durations[@]}" | sort -n | awk '{a[NR]=$1} END {
        if (NR == 0) { print "-"; exit }
        m = (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2
        printf "%.1f", m / 1000 }')
    printf '%-32s %-10s %5d/%-3d %4d (%d) %9s  %s\n' "$(basename "$mission")" \
        "$(basename "$world" .toml)" "$ok" "$runs" "$hits" "$hit_runs" "$median" "${failed[*]:-}"
done
