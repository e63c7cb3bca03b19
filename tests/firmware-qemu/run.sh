#!/usr/bin/env bash
# The firmware's tasks (link, pipeline, roller, effects) on QEMU's Cortex-M7 board
# (mps2-an500, -icount shift=0) with the firmware's statics, stack size and stack guard,
# against mock peripherals (src/mcu/). Prints and writes target/firmware-qemu/report.txt,
# and fails unless:
#   - the stack's high-water mark leaves at least 25 % of the stack;
#   - no step came more than 50 µs late while frames were fused (the roller at interrupt
#     priority), and the same run with the roller in thread mode, as the firmware once
#     ran it, is later than that (so the measurement can tell);
#   - a host that stops reading stops the roller within the heartbeat and 0.5 s, and a
#     new host that then opens the device (no bus reset) has its first Hello answered
#     alone (the mock IN endpoint holds a loaded packet as the OTG core does);
#   - a Stop reaches the roller within 10 ms while the link's send is stuck on a host
#     that reads nothing;
#   - the pipeline keeps up with the sensor: at least 57 of the 60 frames it sends in the
#     two-second window are fused;
#   - the tiles' USB load while streaming is under half of full speed's bulk rate
#     (1.23 MB/s in this model: a 64-byte packet every 52 µs);
#   - the final status of the session arrived, with the fusions' cycles measured, and
#     every task kept beating;
#   - reading the stack guard faults (a run built with --features touch-guard).
#
#   bash tests/firmware-qemu/run.sh
#
# Needs the thumbv7em-none-eabihf target and qemu-system-arm (Debian: qemu-system-arm).
set -euo pipefail
cd "$(dirname "$0")"
root="$(cd ../.. && pwd)"
target=thumbv7em-none-eabihf
out="$root/target/firmware-qemu"
mkdir -p "$out"
elf="$root/target/$target/release/rollfuse-firmware-qemu"

cargo build -q --release --target "$target" --target-dir "$root/target"
cp "$elf" "$out/interrupt.elf"
cargo build -q --release --features roller-in-thread --target "$target" --target-dir "$root/target"
cp "$elf" "$out/thread.elf"
cargo build -q --release --features touch-guard --target "$target" --target-dir "$root/target"
cp "$elf" "$out/touch-guard.elf"

# sleep=off: while the board idles, its time jumps to the next timer deadline instead of
# passing at the host's speed, so every machine sees the same board time.
run() {
    timeout 600 qemu-system-arm -machine mps2-an500 -cpu cortex-m7 -icount shift=0,sleep=off \
        -nographic -monitor none -serial none \
        -semihosting-config enable=on,target=native -kernel "$1"
}

# The thread-mode run beside the main one: board time is counted in instructions, so
# sharing the host's cores changes no figure (and saves one run's 80 s).
run "$out/thread.elf" > "$out/thread.log" 2>&1 &
thread_run=$!
session=$(run "$out/interrupt.elf") || {
    kill "$thread_run" 2>/dev/null || true
    printf '%s\n' "$session"
    echo "firmware-qemu: FAIL: the run ended in a fault or a failed check" >&2
    exit 1
}
wait "$thread_run" || true
thread=$(grep '^step lateness' "$out/thread.log" || true)
guard=$(run "$out/touch-guard.elf" | head -1 || true)
{
    echo "# the firmware's tasks on QEMU mps2-an500 (Cortex-M7, -icount shift=0,sleep=off, 400 instructions a board microsecond)"
    printf '%s\n' "$session"
    echo "as the firmware once ran it, $thread"
    echo "stack guard: $guard"
} > "$out/report.part"
mv "$out/report.part" "$out/report.txt"
cat "$out/report.txt"

awk '
    /^stack high-water:/ { used = $3; size = $6 }
    /^step lateness:/ { late = $4; fused = $10 }
    /^usb load:/ { load = $(NF - 1) }
    /^as the firmware once ran it, step lateness:/ { thread_late = $9 }
    /^host gone: roller stopped/ { stopped_ms = $5; heartbeat_ms = $12 + 0 }
    /final status received/ { ended = 1 }
    /^stop while sending: roller told to stop/ { stop_us = $8 }
    /^fusion cycles in the status:/ { cycles_mean = $7 }
    /^reconnect: a new host.s first Hello answered on the first try/ { reconnected = 1 }
    /^watchdog:/ { missed = $2 }
    /^stack guard: hard fault/ { guarded = 1 }
    END {
        bad = ""
        if (size == "" || used > 0.75 * size) bad = bad "\n  stack: " used " of " size " leaves under 25 %"
        if (late == "" || late > 50) bad = bad "\n  a step came " late " us late (bound 50 us)"
        if (thread_late == "" || thread_late <= 50) bad = bad "\n  thread mode was not later than the bound: the lateness measurement cannot tell"
        if (stopped_ms == "" || stopped_ms > heartbeat_ms + 500) bad = bad "\n  the roller did not stop within the heartbeat and 0.5 s"
        if (stop_us == "" || stop_us > 10000) bad = bad "\n  a Stop sent during a stuck send reached the roller after " stop_us " us (bound 10 ms)"
        if (fused == "" || fused < 57) bad = bad "\n  " fused " frames fused in the window (at least 57 of the 60 the sensor sends)"
        if (load == "" || load > 615) bad = bad "\n  the tiles took " load " kB/s of USB (bound 615 kB/s)"
        if (!ended) bad = bad "\n  the final status did not arrive"
        if (!reconnected) bad = bad "\n  a new host after a dead one did not get its first Hello answered alone"
        if (cycles_mean == "" || cycles_mean == 0) bad = bad "\n  the status reported no fusion cycles"
        if (!guarded) bad = bad "\n  reading the stack guard did not fault"
        if (missed != "0") bad = bad "\n  a task stopped beating (the watchdog would restart the board)"
        if (bad != "") { print "firmware-qemu: FAIL" bad; exit 1 }
        print "firmware-qemu: ok"
    }' "$out/report.txt" >&2
