#!/usr/bin/env bash
# Install lavapipe (Mesa's CPU Vulkan driver) from Mesa 25 on Debian 12: add the
# bookworm-backports suite by copying the machine's own Debian apt source (so no
# mirror host is written here), then install mesa-vulkan-drivers from it.
# Mesa 22.3 (plain bookworm) also works, slower and without ray queries.
set -euo pipefail
. /etc/os-release
codename="${VERSION_CODENAME:-}"
if [ "${ID:-}" != "debian" ] || [ -z "$codename" ]; then
    echo "not Debian: installing the distribution's mesa-vulkan-drivers"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mesa-vulkan-drivers libvulkan1 >/dev/null
    exit 0
fi
backports="/etc/apt/sources.list.d/celray-${codename}-backports.sources"
if [ ! -f "$backports" ]; then
    src=""
    for f in /etc/apt/sources.list.d/debian.sources /etc/apt/sources.list.d/*.sources; do
        [ -f "$f" ] && grep -qE "^Suites:.*\b${codename}\b" "$f" && { src="$f"; break; }
    done
    if [ -n "$src" ]; then
        # deb822: the first stanza whose Suites names the release itself.
        awk -v rel="$codename" -v bp="${codename}-backports" '
            BEGIN { RS = ""; FS = "\n" }
            {
                keep = 0
                for (i = 1; i <= NF; i++) if ($i ~ "^Suites:" && (" " $i " ") ~ (" " rel " ")) keep = 1
                if (keep && !done) {
                    for (i = 1; i <= NF; i++) {
                        if ($i ~ "^Suites:") print "Suites: " bp
                        else if ($i !~ "^#") print $i
                    }
                    done = 1
                }
            }' "$src" > "$backports"
    elif [ -f /etc/apt/sources.list ]; then
        # one-line format: the first "deb URI codename ..." line, suite replaced.
        line=$(grep -E "^deb[[:space:]]+[^[:space:]]+[[:space:]]+${codename}[[:space:]]" /etc/apt/sources.list | head -n1)
        [ -n "$line" ] || { echo "no Debian apt source for ${codename} found" >&2; exit 1; }
        backports="/etc/apt/sources.list.d/celray-${codename}-backports.list"
        echo "$line" | sed -E "s/[[:space:]]${codename}[[:space:]]/ ${codename}-backports /" > "$backports"
    else
        echo "no Debian apt source found to derive ${codename}-backports from" >&2
        exit 1
    fi
fi
apt-get update -qq
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq -t "${codename}-backports" mesa-vulkan-drivers libvulkan1 >/dev/null
