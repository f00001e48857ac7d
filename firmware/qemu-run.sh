#!/usr/bin/env bash
# Cargo runner for thumbv7em-none-eabihf: boots the ELF on QEMU's mps2-an386 (Cortex-M4F),
# decodes its defmt-over-semihosting log with defmt-print, and exits with the firmware's
# semihosting exit status (0 = pass). Extra QEMU arguments may come in $QEMU_EXTRA.
set -euo pipefail
elf="$1"
shift || true
command -v qemu-system-arm >/dev/null || { echo "qemu-system-arm missing: apt-get install -y qemu-system-arm" >&2; exit 127; }
command -v defmt-print >/dev/null || { echo "defmt-print missing: cargo install defmt-print --locked" >&2; exit 127; }
# shellcheck disable=SC2086
timeout "${QEMU_TIMEOUT:-120}" qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -nographic \
  -semihosting-config enable=on,target=native -icount shift=0 ${QEMU_EXTRA:-} -kernel "$elf" "$@" \
  | defmt-print -e "$elf"
