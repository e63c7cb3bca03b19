#!/usr/bin/env bash
# The firmware's stack, checked statically on its release ELF: each function's frame and
# the deepest call path (tests/firmware-stack/stack.py) against the stack the linker
# leaves (`_stack_start − _stack_end`), with 25 % to spare and no frame over 16 KiB.
#
#   bash tests/firmware-stack/run.sh       # builds the firmware first
set -euo pipefail
cd "$(dirname "$0")/../.."
target=thumbv7em-none-eabihf
cargo build -q -p rollfuse-fw --release --target "$target"
elf="target/$target/release/rollfuse-fw"
objdump=$(command -v arm-none-eabi-objdump || command -v llvm-objdump || true)
nm=$(command -v arm-none-eabi-nm || command -v llvm-nm || true)
if [[ -z "$objdump" || -z "$nm" ]]; then
    echo "firmware-stack: needs arm-none-eabi-objdump and -nm (apt-get install binutils-arm-none-eabi)" >&2
    exit 2
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$objdump" -d --no-show-raw-insn "$elf" > "$work/dis.txt"
"$nm" -n "$elf" > "$work/sym.txt"
addr() { awk -v s="$1" '$3 == s { print $1 }' "$work/sym.txt"; }
start=$(addr _stack_start)
end=$(addr _stack_end)
stack=$((16#$start - 16#$end))
python3 tests/firmware-stack/stack.py "$work/dis.txt" "$work/sym.txt" "$stack"
