#!/usr/bin/env bash
# cargo-mutants on the code a change touches: every mutant cargo-mutants makes in the lines
# changed since the commit in .ci/mutants-base (the files `.cargo/mutants.toml` examines:
# the tick path of controller-core, plant-host's step and event code, pil-link's session)
# must be caught by its own crate's tests. Fails if any is missed or times out.
#   bash tools/mutants-diff.sh            (against .ci/mutants-base)
#   bash tools/mutants-diff.sh <commit>   (against another base)
# MUTANTS_PROFILE=mutants picks the cargo profile (default: test).
# The report of each crate is in target/mutants-diff/<crate>/mutants.out/.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
base="${1:-$(tr -d '[:space:]' <.ci/mutants-base)}"
out="$root/target/mutants-diff"
mkdir -p "$out"
# Against the working tree, so uncommitted edits count too.
git diff "$base" -- '*.rs' >"$out/changes.diff"
echo "mutants-diff: $(grep -c '^+++ ' "$out/changes.diff" || true) Rust files changed since $base"
# cargo-mutants builds each mutant in a scratch copy of the tree; with the target directory
# shared, a mutant rebuilds only the crate it is in (and its tests). The test profile, not
# the full runs' `mutants` profile: in CI `cargo test` has just built every dependency for
# it, where the `mutants` profile would build them all again (4 min for controller-core's
# alone at load average 5), for a mutant that takes about 5 s longer to build.
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
profile="${MUTANTS_PROFILE:-test}"
status=0
for pkg in controller-core plant-host pil-link; do
  features=()
  # pil-link's socket tests (tests/it/session.rs) need its `std` feature.
  if [[ $pkg == pil-link ]]; then features=(--features std); fi
  cargo mutants -p "$pkg" "${features[@]}" --in-diff "$out/changes.diff" --profile "$profile" \
    --colors never -o "$out/$pkg" || status=$?
done
exit "$status"
