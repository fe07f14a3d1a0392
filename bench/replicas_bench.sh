#!/usr/bin/env bash
# Replicas behind nginx: rooms/s and request->room latency that players get through
# nginx with 1, 2 and 3 grotto-server replicas, and from 1 replica without nginx. grotto-load in
# burst mode with --spread: every player stands in a sector of its own and wants everything
# within --radius, so every room is really built (fresh replicas, cold caches, for each
# measurement). A round measures the four set-ups one after another and its ratios are to that
# round's direct single replica; the report gives each figure's median over the rounds.
# Everything shares this machine's cores (2 here): more replicas add no CPU, so the ratios show
# the balancer's overhead and what splitting the work costs, not scaling.
#
#   bench/replicas_bench.sh GROTTO_SERVER GROTTO_LOAD [OUT.json] [ROUNDS] [PLAYERS] [RADIUS_M]
# Exit: 0 with the report written, 1 when a measurement failed, 2 on a bad argument.
set -u
[[ "${1:-}" == -h || "${1:-}" == --help ]] && { sed -n '2,/^set -u/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; exit 0; }
for a in "$@"; do
  [[ "$a" != -* ]] || { echo "replicas_bench: unknown flag '$a' (--help)" >&2; exit 2; }
done
(($# >= 2)) || { echo "replicas_bench: GROTTO_SERVER and GROTTO_LOAD are required (--help)" >&2; exit 2; }
GROTTO_SERVER=${1:?usage: replicas_bench.sh GROTTO_SERVER GROTTO_LOAD [OUT.json] [ROUNDS] [PLAYERS] [RADIUS_M]}
GROTTO_LOAD=${2:?usage: replicas_bench.sh GROTTO_SERVER GROTTO_LOAD [OUT.json] [ROUNDS] [PLAYERS] [RADIUS_M]}
out=${3:-replicas_bench.json} rounds=${4:-3} players=${5:-16} radius=${6:-100}
for v in rounds players; do
  [[ "${!v}" =~ ^[1-9][0-9]*$ ]] || { echo "replicas_bench: $v must be a whole number >= 1 (got '${!v}')" >&2; exit 2; }
done
[[ "$radius" =~ ^[0-9]+([.][0-9]+)?$ ]] || { echo "replicas_bench: RADIUS_M must be a number (got '$radius')" >&2; exit 2; }
source "$(dirname "$0")/../tests/deploy/lb_common.sh"
lb_init replicas-bench

# Worlds: one per player (grotto-load --seeds), so that nginx's hash on the seed has something to
# spread; every replica has room for all of them besides its own (--max-worlds). One more set-up,
# oneworld_1, is the direct single replica with every player in one world (--seed 101): what
# serving many worlds costs a replica.
world_args=(--seeds "$(seq -s, 101 $((100 + players)))")
lb_replica_args=(--max-worlds "$((players + 1))")

# measure NAME REPLICAS VIA: one grotto-load burst; prints "rooms_per_s p50 p90 p99 rooms".
measure() {
  local name=$1 n=$2 via=$3 url json="$lb_dir/$1.json" worlds=("${world_args[@]}")
  lb_start_replicas "$n"
  if [[ "$via" == nginx ]]; then
    lb_start_nginx
    url="ws://127.0.0.1:$lb_nginx_port/ws"
  else
    url="ws://127.0.0.1:${lb_replica_port[0]}/ws"
  fi
  [[ "$via" == oneworld ]] && worlds=(--seed 101)
  timeout 120 "$GROTTO_LOAD" --server "$url" --mode burst --spread "${worlds[@]}" \
    --players "$players" --radius "$radius" --quiet --json "$json" >"$lb_dir/$name.log" 2>&1 ||
    lb_fail "grotto-load ($name) exited $?: $(tail -n 5 "$lb_dir/$name.log")"
  lb_stop_all
  echo "$(lb_json "$json" rooms_per_s) $(lb_json "$json" latency_ms.p50) $(lb_json "$json" latency_ms.p90) $(lb_json "$json" latency_ms.p99) $(lb_json "$json" rooms.ready)"
}

median() { tr ' ' '\n' | sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }

setups=(direct_1 nginx_1 nginx_2 nginx_3 oneworld_1)
declare -A rate p50 p90 p99 rooms ratio
for ((r = 1; r <= rounds; r++)); do
  declare -A row=()
  for s in "${setups[@]}"; do
    n=${s#*_} via=${s%_*}
    read -r row_rate row_p50 row_p90 row_p99 row_rooms < <(measure "$s-$r" "$n" "$via")
    [[ -n "$row_rate" ]] || lb_fail "no result for $s in round $r"
    rate[$s]+="$row_rate " p50[$s]+="$row_p50 " p90[$s]+="$row_p90 " p99[$s]+="$row_p99 "
    rooms[$s]+="$row_rooms "
    row[$s]=$row_rate
    echo "round $r $s: $row_rate rooms/s, latency p50 $row_p50 p90 $row_p90 p99 $row_p99 ms, $row_rooms rooms" >&2
  done
  for s in "${setups[@]}"; do
    ratio[$s]+="$(awk -v a="${row[$s]}" -v b="${row[direct_1]}" 'BEGIN { printf "%.4f", a / b }') "
  done
done

{
  echo "{"
  echo "  \"bench\": \"replicas_bench\","
  echo "  \"cores\": $(nproc),"
  echo "  \"rounds\": $rounds, \"players\": $players, \"radius_m\": $radius, \"mode\": \"burst --spread\","
  echo "  \"worlds\": \"${world_args[*]}\","
  echo "  \"note\": \"replicas, nginx and grotto-load share the same cores; figures are medians over rounds; ratio_to_direct is rooms/s over the same round's direct single replica\","
  echo "  \"setups\": {"
  for i in "${!setups[@]}"; do
    s=${setups[$i]}
    printf '    "%s": {"replicas": %s, "via": "%s", "rooms_per_s": %s, "ratio_to_direct": %s, "latency_ms": {"p50": %s, "p90": %s, "p99": %s}, "rooms": %s, "rooms_per_s_runs": [%s]}%s\n' \
      "$s" "${s#*_}" "${s%_*}" "$(median <<<"${rate[$s]% }")" "$(median <<<"${ratio[$s]% }")" \
      "$(median <<<"${p50[$s]% }")" "$(median <<<"${p90[$s]% }")" "$(median <<<"${p99[$s]% }")" \
      "$(median <<<"${rooms[$s]% }")" "$(sed 's/ *$//; s/ /, /g' <<<"${rate[$s]}")" \
      "$([[ $i -lt $((${#setups[@]} - 1)) ]] && echo ,)"
  done
  echo "  }"
  echo "}"
} >"$out"
cat "$out"
