#!/usr/bin/env bash
# Runs the firmware under QEMU and checks what it says (the firmware's own smoke test):
#   1. `cargo run --release --features bench` exits 0 and prints the start-up line, the
#      cost meter's calibration (40 instructions per SysTick tick) and the bench figures;
#   2. the device image, with UART0 on a Unix socket, answers the protocol's Hello
#      (scripts/uart_hello_check.py) and logs "lssi firmware up" and "lssi device ready".
# The full replay through the device image is tests/tests/qemu.rs (scripts/ci-qemu.sh).
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

echo "== device image under QEMU, UART0 on a Unix socket"
cargo build --release --locked --quiet || exit 1
sock="$work/uart.sock"
# The device loops until `timeout` stops QEMU (status 124): give it long enough to boot and
# answer, then wait for it rather than kill it (timeout runs QEMU in a process group of its own).
LSSI_TIMEOUT=10 LSSI_SERIAL="-serial unix:$sock,server=on,wait=off" \
    cargo run --release --locked --quiet >"$work/device.out" 2>&1 &
device=$!
if python3 scripts/uart_hello_check.py "$sock"; then
    echo "ok   UART Hello"; passed=$((passed + 1))
else
    echo "FAIL UART Hello"; failed=$((failed + 1))
fi
wait "$device"
echo "(device ended with status $? after its 10 s timeout; 124 is expected)"
cat "$work/device.out"
check "device start-up line" '^INFO +lssi firmware up' "$work/device.out"
check "device ready line" '^INFO +lssi device ready: window capacity 256, 16 terms' "$work/device.out"

echo "$passed passed, $failed failed"
[[ $failed -eq 0 ]]
