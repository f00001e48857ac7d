#!/usr/bin/env bash
# Hand-run mutation check of the tick path (issue 16): each mutant below is one edit that
# survived every host test of the first version (the fault checks and the AFB form rewritten
# for their issue-15 forms: a limit one count lower is the old `>` to `>=`; the PI's in its
# 32-bit step, the path the shipped drives run). The script
# applies each to a scratch copy of the tree, runs the tests that should catch it, and
# reports KILLED or SURVIVED.
#   bash tools/mutants.sh            (each mutant rebuilds only what it touches, incrementally)
# The doctests are left out (`--lib --tests`): each is compiled on its own, which made
# them most of a mutant's time, and none is needed to kill a mutant below.
set -uo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
tar -C "$root" --exclude=./target --exclude=./out --exclude=./.git -cf - . | tar -C "$work" -xf -
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target/mutants}"

# name @ file @ perl substitution (applied with -0pi, so it may span lines) @ test command
mutants=(
  "pi output: feed-forward sign@controller-core/src/pi.rs@s/let u = p \+ ff \+ \(i_next >> 16\) as i32;/let u = p - ff + (i_next >> 16) as i32;/@cargo test -q -p controller-core --lib --tests"
  "pi anti-windup: feed-forward sign@controller-core/src/pi.rs@s/let u_trial = p \+ ff \+ offset \+ i_whole;/let u_trial = p - ff + offset + i_whole;/@cargo test -q -p controller-core --lib --tests"
  "differentiator in velocity tick: || to &&@controller-core/src/controller/coefficients.rs@s/(diff_in_velocity_tick: cfg\.velocity_estimator == Estimator::Differentiation\s*)\|\|/\1&&/@cargo test -q -p controller-core --lib --tests"
  "observer load torque: sign@controller-core/src/controller/coefficients.rs@s/k_load: quantize\(-g\.observer_inertia_s/k_load: quantize(g.observer_inertia_s/@cargo test -q -p controller-core --lib --tests"
  "differentiator: first-sample arm deleted@controller-core/src/differentiator.rs@s/\s*0 => \(0, 0\),//@cargo test -q -p controller-core --lib --tests"
  "differentiator: second-sample arm deleted@controller-core/src/differentiator.rs@s/\s*1 => \(delta, 0\),//@cargo test -q -p controller-core --lib --tests"
  "encoder jump: trips at the limit, not only above it@controller-core/src/controller/coefficients.rs@s/(encoder_jump_margin × overspeed\)\",\s*\)\?\s*\.to_num::<i32>\(\)\s*\.unsigned_abs\(\))/\$1.saturating_sub(1)/@cargo test -q -p controller-core --lib --tests"
  "magnitude check: > to >=@controller-core/src/controller/coefficients.rs@s/\.wrapping_add\(self\.0\) > self\.0 << 1/.wrapping_add(self.0) >= self.0 << 1/@cargo test -q -p controller-core --lib --tests"
  "overspeed: trips at the limit, not only above it@controller-core/src/controller/coefficients.rs@s/(\"faults\.overspeed_pu\"\)\?\s*\.to_bits\(\)\s*\.unsigned_abs\(\))/\$1.saturating_sub(1)/@cargo test -q -p controller-core --lib --tests"
  "following error: trips at the limit, not only above it@controller-core/src/controller/coefficients.rs@s/(\"faults\.following_error_counts\",\s*\)\?\s*\.to_bits\(\)\s*\.unsigned_abs\(\))/\$1.saturating_sub(1)/@cargo test -q -p controller-core --lib --tests"
  "closed-form AFB: input sign@controller-core/src/accel_feedback.rs@s/let x_p = c\.saturating_sub\(predict\(p\)\);/let x_p = predict(p).saturating_sub(c);/@cargo test -q -p controller-core --lib --tests"
  "closed-form AFB: filter finished with P, not the applied T@controller-core/src/accel_feedback.rs@s/filter\.finish\(s, h46, c\.saturating_sub\(predict\(t\)\)\);/filter.finish(s, h46, c.saturating_sub(predict(p)));/@cargo test -q -p controller-core --lib --tests"
  "closed-form AFB: error form loses the commanded acceleration@controller-core/src/controller/afb.rs@s/(let c = if step == AfbStep::ClosedError \{\s*)self\.state\.accel_cmd/\$1PuPerS::ZERO/@cargo test -q -p controller-core --lib --tests"
  "closed-form AFB: applied torque P - afb@controller-core/src/accel_feedback.rs@s/let t = p\.saturating_add\(afb\)/let t = p.saturating_sub(afb)/@cargo test -q -p controller-core --lib --tests"
  "lost motion: half the dead zone@plant-host/src/config/mod.rs@s/half_gap_rad: 0\.5 \* self\.backlash_deg/half_gap_rad: 0.25 * self.backlash_deg/@cargo test -q -p plant-host --lib --tests"
)

killed=0; survived=0; broken=0
for m in "${mutants[@]}"; do
  IFS='@' read -r name file subst cmd <<<"$m"
  if [[ ! -f "$root/$file" ]]; then
    echo "NOT APPLIED  $name (no file $file)"; broken=$((broken + 1)); continue
  fi
  cp "$root/$file" "$work/$file.orig"
  perl -0pi -e "$subst" "$work/$file"
  if cmp -s "$work/$file" "$work/$file.orig"; then
    echo "NOT APPLIED  $name (pattern not found in $file)"; broken=$((broken + 1))
  elif ! (cd "$work" && $cmd --no-run >/dev/null 2>&1); then
    echo "NO BUILD     $name (the mutant does not compile: not a test result)"; broken=$((broken + 1))
  elif (cd "$work" && $cmd >/dev/null 2>&1); then
    echo "SURVIVED     $name"; survived=$((survived + 1))
  else
    echo "KILLED       $name"; killed=$((killed + 1))
  fi
  mv "$work/$file.orig" "$work/$file"
done
echo "mutants: $killed killed, $survived survived, $broken not applied or not built"
[[ $survived -eq 0 && $broken -eq 0 ]]
