#!/usr/bin/env bash
# count-test-results.sh LOG: sum the "test result:" lines of a `cargo test`
# log (one per test binary: "test result: ok. 12 passed; 0 failed; 1 ignored;
# ..."), print the totals, and fail when a test failed, a binary reported
# FAILED, or no test ran at all. Used by tools/test-all.sh.
set -euo pipefail
log=${1:?usage: count-test-results.sh LOG}
awk '
/^test result:/ {
    binaries++
    if ($3 != "ok.") bad++
    for (i = 4; i <= NF; i++) {
        if ($i ~ /^passed;?$/) passed += $(i - 1)
        if ($i ~ /^failed;?$/) failed += $(i - 1)
    }
}
END {
    printf "%d test binaries: %d passed, %d failed\n", binaries, passed, failed
    if (binaries == 0 || passed == 0) { print "no test ran" > "/dev/stderr"; exit 1 }
    if (failed > 0 || bad > 0) { print "some tests failed" > "/dev/stderr"; exit 1 }
}' "$log"
