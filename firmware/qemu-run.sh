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
#   defmt stream. UART_INPUT=<file> feeds that file to UART0's receiver (a `d` asks the
#   firmware for a trace dump): `UART_INPUT=<(printf d) cargo fw-run`.
# * Extra QEMU arguments may come in $QEMU_EXTRA; QEMU_TIMEOUT (s) bounds the run.
set -euo pipefail
elf="$1"
shift || true
# `--plain-log` (first argument after the ELF): print only the log messages, no level
# prefix, so result lines read `current_tick_instructions: N` (cargo fw-bench).
# `--expect-crash`: the image must die in its HardFault/panic handler: pass (0) only on
# exit status 1 with a `HardFault` or `panic` line in the log (cargo fw-crash-check).
log_format=()
expect_crash=0
while [[ $# -gt 0 ]]; do
  case "$1" in
    --plain-log) log_format=(--log-format "{s}"); shift ;;
    --expect-crash) expect_crash=1; shift ;;
    *) break ;;
  esac
done
command -v qemu-system-arm >/dev/null || { echo "qemu-system-arm missing: apt-get install -y qemu-system-arm" >&2; exit 127; }
command -v defmt-print >/dev/null || { echo "defmt-print missing: cargo install defmt-print --locked" >&2; exit 127; }
# append=on: QEMU must not truncate stderr when it is a regular file (a CI log).
serial=(-chardev file,id=uart0,path=/dev/stderr,append=on -serial chardev:uart0)
if [[ -n "${UART_INPUT:-}" ]]; then
  # A named-pipe pair (QEMU's `pipe:` backend opens <base>.in and <base>.out read-write):
  # the input file is fed to UART0 RX, UART0 TX is copied to stderr.
  fifo_dir="$(mktemp -d)"
  mkfifo "$fifo_dir/uart.in" "$fifo_dir/uart.out"
  cat "$fifo_dir/uart.out" >&2 &
  cat "$UART_INPUT" >"$fifo_dir/uart.in" &
  serial=(-serial "pipe:$fifo_dir/uart")
fi
run_qemu() {
# shellcheck disable=SC2086
timeout "${QEMU_TIMEOUT:-120}" qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -nographic \
  -monitor none "${serial[@]}" \
  -semihosting-config enable=on,target=native -icount shift=0,sleep=off ${QEMU_EXTRA:-} \
  -kernel "$elf" "$@" \
  | defmt-print -e "$elf" "${log_format[@]}"
}
if [[ $expect_crash -eq 0 ]]; then
  run_qemu "$@"
  exit 0
fi
log="$(mktemp)"
trap 'rm -f "$log"' EXIT
status=0
run_qemu "$@" | tee "$log" || status=$?
if [[ $status -eq 1 ]] && grep -qE "HardFault|panic" "$log"; then
  echo "expected crash: exit status 1 with the fault logged"
  exit 0
fi
echo "expected a logged crash with exit status 1, got status $status" >&2
exit 1
