#!/usr/bin/env bash
# The JavaScript library the flight report page (`rotorpilot report`) inlines,
# taken from npm at a pinned version and checked against the registry's
# integrity hash: uPlot (MIT), its minified IIFE build, its CSS and its
# licence, copied into report/vendor/ (include_str! puts them into the
# binary, so `cargo install` needs no network).
#
#   tools/vendor_report_assets.sh          fetch and (re)write report/vendor/
#   tools/vendor_report_assets.sh --check  fail when report/vendor/ differs
#                                          from the pinned tarball (CI)
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGE=uplot
VERSION=1.6.32
# `npm view uplot@1.6.32 dist.integrity`
INTEGRITY='sha512-KIMVnG68zvu5XXUbC4LQEPnhwOxBuLyW1AHtpm6IKTXImkbLgkMy+jabjLgSLMasNuGGzQm/ep3tOkyTxpiQIw=='
# file in the tarball -> file in report/vendor/
FILES=(
    "package/dist/uPlot.iife.min.js:uPlot.iife.min.js"
    "package/dist/uPlot.min.css:uPlot.min.css"
    "package/LICENSE:LICENSE-uPlot"
)

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
(cd "$work" && npm pack --silent "$PACKAGE@$VERSION" >/dev/null)
tarball="$work/$PACKAGE-$VERSION.tgz"
got="sha512-$(openssl dgst -sha512 -binary "$tarball" | base64 -w0)"
if [ "$got" != "$INTEGRITY" ]; then
    echo "vendor_report_assets: $PACKAGE@$VERSION from npm has integrity $got, pinned $INTEGRITY" >&2
    exit 1
fi
tar -xzf "$tarball" -C "$work"
status=0
for pair in "${FILES[@]}"; do
    from="$work/${pair%%:*}"
    to="report/vendor/${pair##*:}"
    if [ "${1:-}" = "--check" ]; then
        if ! cmp -s "$from" "$to"; then
            echo "vendor_report_assets: $to differs from ${pair%%:*} of $PACKAGE@$VERSION (run tools/vendor_report_assets.sh)" >&2
            status=1
        fi
    else
        cp "$from" "$to"
        echo "wrote $to ($(wc -c <"$to") bytes, sha256 $(sha256sum "$to" | cut -c1-16)...)"
    fi
done
if [ "${1:-}" = "--check" ] && [ $status = 0 ]; then
    echo "report/vendor/ is $PACKAGE@$VERSION as npm serves it (integrity checked)"
fi
exit $status
