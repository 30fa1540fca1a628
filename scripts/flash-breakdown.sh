#!/usr/bin/env bash
# What the device image's flash holds: .text and .rodata symbols summed by crate, and the
# largest symbols (llvm-nm -S; Rust names demangled, generic impls named by their crate).
#
#   scripts/flash-breakdown.sh                 # the device image (crates/lssi-firmware)
#   scripts/flash-breakdown.sh ELF [TOP]       # any ELF; TOP largest symbols (default 20)
#
# The sums cover the named symbols only: the vector table and linker padding are not
# symbols of a crate, so the total is a little under llvm-size's .text + .rodata.
# Needs llvm-nm from `rustup component add llvm-tools` (scripts/setup.sh installs it).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
elf=${1:-}
top=${2:-20}
if [[ -z $elf ]]; then
    (cd "$root/crates/lssi-firmware" && cargo build --release --locked --quiet --bin lssi-firmware)
    elf="$root/crates/lssi-firmware/target/thumbv7em-none-eabihf/release/lssi-firmware"
fi
if [[ ! -f $elf ]]; then
    echo "flash-breakdown: $elf is not a file" >&2
    exit 2
fi
host=$(rustc -vV | sed -n 's/^host: //p')
nm="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-nm"
if [[ ! -x $nm ]]; then
    echo "flash-breakdown: $nm not found; run: rustup component add llvm-tools" >&2
    exit 1
fi

"$nm" -S --size-sort --radix=d -C "$elf" | awk -v top="$top" -v elf="$(basename "$elf")" '
    # Lines: address size type name. Only code and read-only data count (flash).
    $3 ~ /^[tTrR]$/ {
        size = $2 + 0
        name = $0
        sub(/^[^ ]+ +[^ ]+ +[^ ]+ +/, "", name)
        crate = name
        sub(/^[<&*]+/, "", crate)
        sub(/^(impl|dyn) /, "", crate)
        sub(/^_\$LT\$/, "", crate)
        sub(/\.\..*/, "", crate)
        # Mangled generic impls: lssi_core::identifier::..._$LT$impl...
        if (crate ~ /^compiler_builtins|^__aeabi|^__[a-z]+[sd]f[0-9]/) crate = "compiler_builtins (soft float, mem*)"
        else if (crate ~ /^__/ || crate ~ /^\.L/) crate = "(vector table, anonymous constants)"
        else {
            sub(/::.*/, "", crate); sub(/[ <>$].*/, "", crate)
            if (crate !~ /^[a-z][a-z0-9_]*_[a-z0-9_]*$|^(core|libm|postcard|heapless|defmt|cobs|semihosting|crc|cortex_m|serde)$/)
                crate = "(other: start-up, libc-like, anonymous)"
        }
        if (crate ~ /^(u8|u16|u32|u64|usize|i32|i64|f32|f64|bool|str)$/) crate = "core"
        by[crate] += size
        total += size
        n++
        sizes[n] = size
        names[n] = name
    }
    END {
        printf "%s: %d bytes of .text + .rodata in named symbols\n\n", elf, total
        printf "| crate | bytes | share |\n|---|---:|---:|\n"
        # Selection sort of the few crates, largest first.
        for (c in by) { keys[++k] = c }
        for (i = 1; i <= k; i++) for (j = i + 1; j <= k; j++)
            if (by[keys[j]] > by[keys[i]]) { t = keys[i]; keys[i] = keys[j]; keys[j] = t }
        for (i = 1; i <= k; i++)
            if (by[keys[i]] >= 64) printf "| %s | %d | %.1f %% |\n", keys[i], by[keys[i]], 100 * by[keys[i]] / total
        printf "\nThe %d largest symbols:\n\n| bytes | symbol |\n|---:|---|\n", top
        # llvm-nm sorted by size ascending: the last lines are the largest.
        for (i = n; i > n - top && i > 0; i--) {
            s = names[i]
            gsub(/_\$LT\$impl\$u20\$/, "<impl ", s)
            gsub(/\$LT\$/, "<", s); gsub(/\$GT\$/, ">", s); gsub(/\$C\$/, ",", s)
            gsub(/\$u20\$/, " ", s); gsub(/\.\./, "::", s)
            sub(/::h[0-9a-f]+$/, "", s)
            printf "| %d | `%s` |\n", sizes[i], s
        }
    }'
