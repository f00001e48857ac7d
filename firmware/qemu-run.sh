#!/usr/bin/env bash
# Cargo runner for thumbv7em-none-eabihf: boots the ELF on QEMU's mps2-an386 (Cortex-M4F),
# decodes its defmt-over-semihosting log (stdout) with defmt-print, and exits with the
# firmware's semihosting exit status (0 = pass; a panic or HardFault exits 1).
#
# * `-icount shift=0,sleep=off`: one instruction = one virtual ns, and idle time (WFI) jumps
#   straight to the next timer deadline, so timer periods, SysTick readings and the
#   instruction counts of `cargo fw-bench` are exact and repeatable (with sleep=on the idle
#   time follows the host's real time and the 4 kHz period drifts by several percent).
# * UART0 (the board's console: trace dumps) goes to stderr, kept apart from the binary
#   defmt stream. UART_INPUT=<file> feeds that file to UART0's receiver (e.g. a `d` asks
#   the firmware for a trace dump).
# * Extra QEMU arguments may come in $QEMU_EXTRA; QEMU_TIMEOUT (s) bounds the run.
set -euo pipefail
elf="$1"
shift || true
# `--plain-log` (first argument after the ELF): print only the log messages, no level
# prefix, so result lines read `current_tick_instructions: N` (cargo fw-bench).
log_format=()
if [[ "${1:-}" == "--plain-log" ]]; then
  log_format=(--log-format "{s}")
  shift
fi
command -v qemu-system-arm >/dev/null || { echo "qemu-system-arm missing: apt-get install -y qemu-system-arm" >&2; exit 127; }
command -v defmt-print >/dev/null || { echo "defmt-print missing: cargo install defmt-print --locked" >&2; exit 127; }
if [[ -n "${UART_INPUT:-}" ]]; then
  serial=(-chardev "file,id=uart0,path=/dev/stderr,input-path=${UART_INPUT}" -serial chardev:uart0)
else
  serial=(-serial file:/dev/stderr)
fi
# shellcheck disable=SC2086
timeout "${QEMU_TIMEOUT:-120}" qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -nographic \
  -monitor none "${serial[@]}" \
  -semihosting-config enable=on,target=native -icount shift=0,sleep=off ${QEMU_EXTRA:-} \
  -kernel "$elf" "$@" \
  | defmt-print -e "$elf" "${log_format[@]}"
