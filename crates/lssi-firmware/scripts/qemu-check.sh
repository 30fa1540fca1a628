#!/usr/bin/env bash
# Runs the firmware under QEMU and checks what it says (the firmware's own smoke test):
#   1. `cargo run --release --features bench` exits 0 and prints the start-up line, the
#      cost meter's calibration (40 instructions per SysTick tick) and the bench figures;
#   2. the echo demo, with UART0 on a Unix socket, echoes every byte back
#      (scripts/uart_echo_check.py) and logs "lssi firmware up".
# Needs qemu-system-arm, defmt-print (cargo install defmt-print --locked) and python3.
# Ends with a "N passed, N failed" line; exits 1 if anything failed.
set -uo pipefail
cd "$(dirname "$0")/.."

passed=0
failed=0
check() { # check NAME PATTERN FILE
    if grep -Eq -- "$2" "$3"; then
        echo "ok   $1"; passed=$((passed + 1))
    else
        echo "FAIL $1: no line matching /$2/ in $3"; failed=$((failed + 1))
    fi
}

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "== bench under QEMU"
cargo build --release --locked --quiet --features bench || exit 1
LSSI_TIMEOUT=60 cargo run --release --locked --quiet --features bench >"$work/bench.out" 2>&1
status=$?
cat "$work/bench.out"
if [[ $status -eq 0 ]]; then
    echo "ok   bench exits 0"; passed=$((passed + 1))
else
    echo "FAIL bench exit status $status"; failed=$((failed + 1))
fi
check "start-up line" '^INFO +lssi firmware up' "$work/bench.out"
check "40 instructions per tick" 'cost meter: SysTick in instructions, 40000 milli-instructions per tick' "$work/bench.out"
check "givens16 fit" 'bench givens16: fit max \|error\| 0\.0000[0-9]+' "$work/bench.out"
check "givens16 figures" 'bench givens16: 1000 calls, mean [0-9]+ max [0-9]+ min [0-9]+ instructions/call, stack [0-9]+ bytes' "$work/bench.out"
check "peak stack" 'stack: peak [0-9]+ bytes since reset' "$work/bench.out"

echo "== echo demo under QEMU, UART0 on a Unix socket"
cargo build --release --locked --quiet || exit 1
sock="$work/uart.sock"
# The demo echoes until `timeout` stops QEMU (status 124): give it long enough to boot and
# echo, then wait for it rather than kill it (timeout runs QEMU in a process group of its own).
LSSI_TIMEOUT=10 LSSI_SERIAL="-serial unix:$sock,server=on,wait=off" DEFMT_LOG=debug \
    cargo run --release --locked --quiet >"$work/demo.out" 2>&1 &
demo=$!
if python3 scripts/uart_echo_check.py "$sock"; then
    echo "ok   UART echo"; passed=$((passed + 1))
else
    echo "FAIL UART echo"; failed=$((failed + 1))
fi
wait "$demo"
echo "(demo ended with status $? after its 10 s timeout; 124 is expected)"
cat "$work/demo.out"
check "demo start-up line" '^INFO +lssi firmware up' "$work/demo.out"
check "demo echo count" '^DEBUG +echoed 272 bytes' "$work/demo.out"

echo "$passed passed, $failed failed"
[[ $failed -eq 0 ]]
