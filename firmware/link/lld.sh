#!/usr/bin/env bash
# Linker wrapper for thumbv7em-none-eabihf (set in .cargo/config.toml): runs rust-lld from
# an empty directory. rustc links with the workspace root as the working directory, and
# lld looks for `INCLUDE memory.x` there before the -L paths, so without this the root
# memory.x (mps2-an386) would be linked into every board's image. From an empty directory
# the search falls to firmware's build-script output, where build.rs has put the memory.x
# of the selected board (the root memory.x for QEMU, link/memory-stm32f407.x for the STM32
# board). All other paths rustc passes are absolute.
set -euo pipefail
host="$(rustc -vV | sed -n 's/^host: //p')"
lld="$(rustc --print sysroot)/lib/rustlib/${host}/bin/rust-lld"
[[ -x "$lld" ]] || { echo "lld.sh: rust-lld not found at $lld" >&2; exit 127; }
empty="$(mktemp -d)"
trap 'rmdir "$empty"' EXIT
cd "$empty"
"$lld" "$@"
