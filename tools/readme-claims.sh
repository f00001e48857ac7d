#!/usr/bin/env bash
# The README's claims table is the one `cargo run --release` writes to out/claims.md: the
# lines between `<!-- claims:begin -->` and `<!-- claims:end -->` in README.md.
#   bash tools/readme-claims.sh --check   exit 1 (printing the diff) if the block differs
#   bash tools/readme-claims.sh --write   replace the block with out/claims.md
# CLAIMS=path and README=path pick other files (default: out/claims.md, README.md).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
claims="${CLAIMS:-$root/out/claims.md}"
readme="${README:-$root/README.md}"
begin='<!-- claims:begin -->'
end='<!-- claims:end -->'

usage() {
    echo "usage: $0 --check | --write" >&2
    exit 2
}
[ $# -eq 1 ] || usage
mode="$1"
case "$mode" in --check | --write) ;; *) usage ;; esac

[ -f "$claims" ] || { echo "readme-claims: $claims is missing: run \`cargo run --release\` first" >&2; exit 2; }
[ -f "$readme" ] || { echo "readme-claims: $readme is missing" >&2; exit 2; }
nb=$(grep -cxF -- "$begin" "$readme" || true)
ne=$(grep -cxF -- "$end" "$readme" || true)
if [ "$nb" != 1 ] || [ "$ne" != 1 ]; then
    echo "readme-claims: $readme needs exactly one line '$begin' and one '$end' (found $nb and $ne)" >&2
    exit 2
fi
lb=$(grep -nxF -- "$begin" "$readme" | cut -d: -f1)
le=$(grep -nxF -- "$end" "$readme" | cut -d: -f1)
if [ "$lb" -ge "$le" ]; then
    echo "readme-claims: '$begin' must come before '$end' in $readme" >&2
    exit 2
fi

block="$(mktemp)"
trap 'rm -f "$block" "$block.new"' EXIT
sed -n "$((lb + 1)),$((le - 1))p" "$readme" >"$block"

case "$mode" in
--check)
    if diff -u --label "README.md (claims block)" --label "$claims" "$block" "$claims"; then
        echo "readme-claims: README.md's claims block is $claims"
    else
        echo "readme-claims: README.md's claims block differs from $claims (run $0 --write)" >&2
        exit 1
    fi
    ;;
--write)
    {
        head -n "$lb" "$readme"
        cat "$claims"
        tail -n "+$le" "$readme"
    } >"$block.new"
    cat "$block.new" >"$readme"
    echo "readme-claims: wrote $claims into $readme"
    ;;
esac
