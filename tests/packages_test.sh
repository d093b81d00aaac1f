#!/usr/bin/env bash
# The Debian packages (docs/packages.md), end to end:
#   tests/packages_test.sh BUILD_DIR amd64|arm64
# 1. builds them from BUILD_DIR with scripts/package (cpack);
# 2. checks what is in them against what the packages must be: files and modes, owner
#    root, nothing in /usr/local, no token, stripped binaries of the right machine that
#    run, the unit's contents, conffiles, Depends from dpkg-shlibdeps, copyright and
#    changelog.Debian.gz;
# 3. installs them into a scratch root with their maintainer scripts and checks what
#    those did: the user and its groups, /var/lib/mirrorscan, the token, the unit enabled;
#    reinstalls (the token is kept), purges (token and data gone, user kept);
# 4. runs lintian: no errors (warnings are printed).
#
# Step 3 cannot touch the running system: dpkg runs with --root and
# --force-script-chrootless (the maintainer scripts act on $DPKG_ROOT, which they
# support), under fakeroot (so the chowns to the new user's id are recorded, not done)
# and, when this runs as root, as the unprivileged user nobody (setpriv), whose writes
# outside the scratch root the kernel refuses. The test also compares the system's
# /etc/passwd and /etc/group before and after.
set -euo pipefail

build="$(cd "$1" && pwd)"
arch="$2"
source_dir="$(cd "$(dirname "$0")/.." && pwd)"
work="$(mktemp -d "${TMPDIR:-/tmp}/packages_test.XXXXXX")"
trap 'rm -rf "$work"' EXIT
chmod 0755 "$work"

failures=0
fail() {
  echo "FAIL: $*" >&2
  failures=$((failures + 1))
}
check() {  # check DESCRIPTION COMMAND...: a failing COMMAND is a failure
  local what="$1"
  shift
  if ! "$@"; then fail "$what"; fi
}

echo "== building the packages from $build"
"$source_dir/scripts/package" "$build" "$work/debs" >"$work/debs.txt"
cat "$work/debs.txt"
case "$arch" in
  amd64)
    packages=(mirrorscand mirrorscan)
    machine="Advanced Micro Devices X86-64"
    groups="" ;;
  arm64)
    packages=(mirrorscand)
    machine="AArch64"
    groups="gpio dialout video" ;;
  *) echo "packages_test: unknown architecture $arch" >&2; exit 2 ;;
esac
declare -A deb
for p in "${packages[@]}"; do
  mapfile -t found < <(ls "$work/debs/${p}_"*"_${arch}.deb" 2>/dev/null)
  if ((${#found[@]} != 1)); then
    echo "FAIL: expected one ${p}_*_${arch}.deb, found ${#found[@]}" >&2
    exit 1
  fi
  deb[$p]="${found[0]}"
done
if (($(wc -l <"$work/debs.txt") != ${#packages[@]})); then
  fail "cpack made other packages than ${packages[*]}: $(tr '\n' ' ' <"$work/debs.txt")"
fi

# --- 2. contents ----------------------------------------------------------------------
# The listing's mode for PATH ("" when absent).
mode_of() { awk -v path="./$2" '$6 == path || $6 == path "/" { print $1 }' "$1"; }
expect_mode() {  # expect_mode LISTING PATH MODE
  local got
  got="$(mode_of "$1" "$2")"
  [[ "$got" == "$3" ]] || fail "$(basename "$1" .list): /$2 is '${got:-missing}', expected $3"
}
# Lines "key value" of a unit file's [Service]/[Unit] settings, for exact comparisons.
unit_value() { grep -E "^$2=" "$1" | tail -1 | cut -d= -f2-; }

for p in "${packages[@]}"; do
  d="${deb[$p]}"
  x="$work/extract/$p"
  list="$work/$p.list"
  mkdir -p "$x"
  dpkg-deb -x "$d" "$x"
  dpkg-deb -e "$d" "$x/DEBIAN"
  dpkg-deb -c "$d" | awk '{ print $1, $2, $3, $4, $5, $6 }' >"$list"
  echo "== $p: $(dpkg-deb -f "$d" Package Version Architecture | tr '\n' ' ')"
  check "$p: Package field" [ "$(dpkg-deb -f "$d" Package)" = "$p" ]
  check "$p: Architecture field" [ "$(dpkg-deb -f "$d" Architecture)" = "$arch" ]
  version="$(dpkg-deb -f "$d" Version)"
  check "$p: version $version has a Debian revision" grep -qE '^[0-9.]+-[0-9]+$' <<<"$version"

  # Owners, /usr/local, directory and file modes.
  awk '$2 != "root/root" { bad = 1; print "  owner: " $0 } END { exit bad }' "$list" ||
    fail "$p: files not owned by root/root"
  ! grep -q ' \./usr/local' "$list" || fail "$p: ships files in /usr/local"
  awk '$1 ~ /^d/ && $1 != "drwxr-xr-x" { bad = 1; print "  dir: " $0 } END { exit bad }' "$list" ||
    fail "$p: directories not 0755"
  awk '$1 ~ /^-/ && $1 != "-rw-r--r--" && $1 != "-rwxr-xr-x" { bad = 1; print "  file: " $0 }
       END { exit bad }' "$list" || fail "$p: files neither 0644 nor 0755"
  expect_mode "$list" "usr/bin/$p" -rwxr-xr-x
  expect_mode "$list" "usr/share/doc/$p/copyright" -rw-r--r--
  expect_mode "$list" "usr/share/doc/$p/changelog.Debian.gz" -rw-r--r--
  case "$p" in
    mirrorscand) expect_mode "$list" usr/share/man/man8/mirrorscand.8.gz -rw-r--r-- ;;
    mirrorscan) expect_mode "$list" usr/share/man/man1/mirrorscan.1.gz -rw-r--r-- ;;
  esac

  # No token anywhere: no file named like one, nothing in /var, not the virtual board's
  # development token, no token key in a board.json.
  ! grep -qiE 'token' <(awk '{ print $6 }' "$list") || fail "$p: ships a file named like a token"
  ! grep -qE ' \./var/' "$list" || fail "$p: ships files in /var (postinst makes /var/lib/mirrorscan)"
  # (mirrorscan's help text shows the public development token as an example for the
  # virtual board; the daemon must not contain it: its board.json would then use it.)
  if [[ "$p" == mirrorscand ]] && grep -rqF "virtual-dev-token-not-a-secret" "$x"; then
    fail "$p: contains the virtual board's development token"
  fi
  while IFS= read -r board; do
    [[ "$(jq -r '.service | has("token")' "$board")" == false ]] ||
      fail "$p: ${board#"$x"} has a fixed service.token"
  done < <(find "$x" -name board.json)

  # Every ELF file: the board's machine, stripped (no symbol table, no debug sections).
  while IFS= read -r elf; do
    rel="${elf#"$x"}"
    readelf -h "$elf" | grep -q "Machine: *$machine" || fail "$p: $rel is not $machine"
    if readelf -S -W "$elf" | grep -qE '\.symtab|\.debug_'; then fail "$p: $rel is not stripped"; fi
  done < <(find "$x" -path "$x/DEBIAN" -prune -o -type f -exec sh -c \
             'head -c 4 "$1" | grep -q "^.ELF"' _ {} \; -print)

  # copyright (machine-readable) and changelog.Debian.gz: gzip -9n, this version.
  doc="$x/usr/share/doc/$p"
  check "$p: copyright is machine-readable" grep -q '^Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/' "$doc/copyright"
  if [[ -f "$doc/changelog.Debian.gz" ]]; then
    header="$(od -A n -t u1 -N 10 "$doc/changelog.Debian.gz" | tr -s ' ' | sed 's/^ //')"
    # Bytes: 31 139 8 FLG MTIME(4) XFL OS; -n: no FNAME flag (8) and MTIME 0; -9: XFL 2.
    read -r -a h <<<"$header"
    check "$p: changelog.Debian.gz has no name or time stamp (gzip -n)" \
      [ $((h[3] & 8)) -eq 0 -a "${h[4]}${h[5]}${h[6]}${h[7]}" = 0000 ]
    check "$p: changelog.Debian.gz is gzip -9" [ "${h[8]}" -eq 2 ]
    check "$p: changelog's first entry is $version" \
      grep -qF "($version)" <(zcat "$doc/changelog.Debian.gz" | head -1)
  fi

  # Depends: dpkg-shlibdeps' libraries (libc6 at least) plus the explicit ones.
  depends="$(dpkg-deb -f "$d" Depends)"
  echo "   Depends: $depends"
  check "$p: Depends has libc6 (dpkg-shlibdeps ran)" grep -qE '(^|, )libc6( |,|$)' <<<"$depends"
done

# The programs run (the arm64 one under qemu, as the aarch64 tests do).
run_arch() {
  if [[ "$arch" == arm64 ]]; then
    qemu-aarch64 -L /usr/aarch64-linux-gnu -E LD_LIBRARY_PATH=/usr/aarch64-linux-gnu/lib "$@"
  else
    "$@"
  fi
}
xd="$work/extract/mirrorscand"
check "mirrorscand --version runs" grep -qE '^mirrorscand [0-9]' <(run_arch "$xd/usr/bin/mirrorscand" --version 2>&1)
if [[ -n "${deb[mirrorscan]:-}" ]]; then
  check "mirrorscan --help runs" grep -q 'device' <("$work/extract/mirrorscan/usr/bin/mirrorscan" --help 2>&1)
fi

# mirrorscand's own files.
dl="$work/mirrorscand.list"
expect_mode "$dl" lib/systemd/system/mirrorscand.service -rw-r--r--
expect_mode "$dl" etc/mirrorscan/board.json -rw-r--r--
expect_mode "$dl" usr/share/mirrorscan/web/index.html -rw-r--r--
expect_mode "$dl" usr/share/mirrorscan/web/app.js -rw-r--r--
if [[ "$arch" == arm64 ]]; then
  expect_mode "$dl" usr/lib/mirrorscan/libmirrorscan_camera_libcamera.so -rw-r--r--
  expect_mode "$dl" lib/udev/rules.d/60-mirrorscan-gpio.rules -rw-r--r--
  expect_mode "$dl" etc/avahi/services/mirrorscan.service -rw-r--r--
  expect_mode "$dl" usr/share/mirrorscan/boards/rpi4/board.json -rw-r--r--
  check "arm64: /etc/mirrorscan/board.json is rpi5's" cmp -s "$xd/etc/mirrorscan/board.json" "$source_dir/boards/rpi5/board.json"
  check "arm64: the token file is board.json's" [ "$(jq -r .service.token_file "$xd/etc/mirrorscan/board.json")" = /var/lib/mirrorscan/token ]
  check "arm64: Depends has gpiod (the unit's ExecStopPost)" grep -qE '(^|, )gpiod( |,|$)' <<<"$(dpkg-deb -f "${deb[mirrorscand]}" Depends)"
else
  scene="$(jq -r .virtual.scene "$xd/etc/mirrorscan/board.json")"
  check "amd64: board.json's scene $scene is in the package" [ -f "$xd$scene" ]
  check "amd64: the token file is /var/lib/mirrorscan/token" [ "$(jq -r .service.token_file "$xd/etc/mirrorscan/board.json")" = /var/lib/mirrorscan/token ]
fi
# Every file in /etc is a conffile, and every conffile is in the package.
diff <(awk '$6 ~ /^\.\/etc\/.*[^\/]$/ { print substr($6, 2) }' "$dl" | sort) \
  <(sort "$xd/DEBIAN/conffiles") || fail "mirrorscand: /etc files and conffiles differ"
for script in postinst prerm postrm; do
  [[ "$(stat -c %a "$xd/DEBIAN/$script")" == 755 ]] || fail "mirrorscand: $script is not 0755"
done

# The unit: Type=notify with a watchdog, restarted on failure, this package's binary with
# the packaged paths, the system user with exactly the board's groups.
unit="$xd/lib/systemd/system/mirrorscand.service"
check "unit: Type=notify" [ "$(unit_value "$unit" Type)" = notify ]
check "unit: NotifyAccess=main" [ "$(unit_value "$unit" NotifyAccess)" = main ]
check "unit: WatchdogSec set" grep -qE '^WatchdogSec=[1-9]' "$unit"
check "unit: Restart=on-failure" [ "$(unit_value "$unit" Restart)" = on-failure ]
check "unit: ExecStart" [ "$(unit_value "$unit" ExecStart)" = \
  "/usr/bin/mirrorscand --board /etc/mirrorscan/board.json --data-dir /var/lib/mirrorscan" ]
check "unit: User=mirrorscan" [ "$(unit_value "$unit" User)" = mirrorscan ]
check "unit: StateDirectory=mirrorscan" [ "$(unit_value "$unit" StateDirectory)" = mirrorscan ]
check "unit: SupplementaryGroups are '$groups'" [ "$(unit_value "$unit" SupplementaryGroups)" = "$groups" ]
! grep -q /usr/local "$unit" || fail "unit: mentions /usr/local"
# Programs the unit runs: in this package, or in a package it depends on (gpioset: gpiod).
declare -A provider=([/usr/bin/gpioset]=gpiod)
daemon_depends="$(dpkg-deb -f "${deb[mirrorscand]}" Depends)"
while read -r program; do
  if [[ -f "$xd$program" ]]; then continue; fi
  if [[ -n "${provider[$program]:-}" ]] && grep -qE "(^|, )${provider[$program]}( |,|$)" <<<"$daemon_depends"; then
    continue
  fi
  fail "unit: $program is neither in the package nor in one it depends on"
done < <(grep -E '^Exec[A-Za-z]*=' "$unit" | cut -d= -f2- | sed 's/^[-@:+!]*//' | awk '{ print $1 }')

# --- 3. install into a scratch root ---------------------------------------------------
sandbox="$work/sandbox"
root="$sandbox/root"
state="$sandbox/fakeroot.state"
mkdir -p "$root/etc" "$root/var/lib/dpkg/updates" "$root/var/lib/dpkg/info" "$root/var/log"
touch "$root/var/lib/dpkg/status" "$state"
# A base system's users and groups (base-passwd's video and dialout; no gpio group).
printf 'root:x:0:0:root:/root:/bin/bash\nnobody:x:65534:65534:nobody:/nonexistent:/usr/sbin/nologin\n' >"$root/etc/passwd"
printf 'root:x:0:\ndialout:x:20:\nvideo:x:44:\nnogroup:x:65534:\n' >"$root/etc/group"
printf 'root:*:19000:0:99999:7:::\nnobody:*:19000:0:99999:7:::\n' >"$root/etc/shadow"
printf 'root:*::\ndialout:*::\nvideo:*::\nnogroup:*::\n' >"$root/etc/gshadow"
cp "${deb[mirrorscand]}" "$sandbox/"
sandbox_deb="$sandbox/$(basename "${deb[mirrorscand]}")"
unprivileged=()
if [[ $(id -u) -eq 0 ]]; then
  chown -R 65534:65534 "$sandbox"
  unprivileged=(setpriv --reuid=65534 --regid=65534 --clear-groups)
fi
# Runs a command as the unprivileged user under fakeroot, keeping fakeroot's record of
# owners and modes in $state.
in_sandbox() {
  "${unprivileged[@]}" env -i HOME="$sandbox" PATH=/usr/sbin:/usr/bin:/sbin:/bin \
    fakeroot -i "$state" -s "$state" -- "$@"
}
fake_stat() { in_sandbox stat -c '%a %u %g' "$1"; }
dpkg_root() {
  in_sandbox dpkg --root="$root" --force-script-chrootless --force-depends \
    --force-architecture --log="$root/var/log/dpkg.log" "$@"
}
system_ids_before="$(cat /etc/passwd /etc/group | sha256sum)"

echo "== installing mirrorscand into the scratch root"
dpkg_root -i "$sandbox_deb" >"$work/install.log" 2>&1 || { cat "$work/install.log"; fail "dpkg -i"; }
entry="$(grep '^mirrorscan:' "$root/etc/passwd" || true)"
echo "   user: $entry"
IFS=: read -r _ _ uid gid _ home shell <<<"$entry"
check "the mirrorscan user exists" [ -n "$entry" ]
check "mirrorscan is a system user (uid $uid < 1000)" [ "${uid:-1000}" -lt 1000 ]
check "mirrorscan's home is /var/lib/mirrorscan" [ "$home" = /var/lib/mirrorscan ]
check "mirrorscan cannot log in" [ "$shell" = /usr/sbin/nologin ]
check "the mirrorscan group is its primary group" grep -qE "^mirrorscan:x:$gid:" "$root/etc/group"
member_of="$(awk -F: '{ n = split($4, m, ","); for (i = 1; i <= n; i++) if (m[i] == "mirrorscan") print $1 }' "$root/etc/group" | sort | tr '\n' ' ')"
expected_groups="$(tr ' ' '\n' <<<"$groups" | sed '/^$/d' | sort | tr '\n' ' ')"
check "mirrorscan is in exactly '$expected_groups' (is in '$member_of')" [ "$member_of" = "$expected_groups" ]
if [[ "$arch" == arm64 ]]; then
  gpio_gid="$(awk -F: '$1 == "gpio" { print $3 }' "$root/etc/group")"
  check "a system group gpio was made (gid ${gpio_gid:-none})" [ "${gpio_gid:-1000}" -lt 1000 ]
fi
check "/var/lib/mirrorscan is 750 mirrorscan's" [ "$(fake_stat "$root/var/lib/mirrorscan")" = "750 $uid $gid" ]
token="$root/var/lib/mirrorscan/token"
check "the token file is 600 mirrorscan's" [ "$(fake_stat "$token")" = "600 $uid $gid" ]
check "the token is 64 hex digits on one line" grep -qxE '[0-9a-f]{64}' "$token"
check "the token is one line" [ "$(wc -l <"$token")" -eq 1 ]
token_value="$(cat "$token")"
check "the unit is enabled (multi-user.target.wants)" \
  [ "$(readlink "$root/etc/systemd/system/multi-user.target.wants/mirrorscand.service")" = /lib/systemd/system/mirrorscand.service ]
check "dpkg says mirrorscand is installed" grep -q '^install ok installed$' \
  <(dpkg-query --admindir="$root/var/lib/dpkg" -W -f='${Status}\n' mirrorscand)

echo "== reinstalling (an upgrade keeps the user and the token)"
dpkg_root -i "$sandbox_deb" >"$work/reinstall.log" 2>&1 || { cat "$work/reinstall.log"; fail "dpkg -i again"; }
check "one mirrorscan user after a reinstall" [ "$(grep -c '^mirrorscan:' "$root/etc/passwd")" -eq 1 ]
check "the token is kept" [ "$(cat "$token" 2>/dev/null)" = "$token_value" ]

echo "== purging"
dpkg_root --purge mirrorscand >"$work/purge.log" 2>&1 || { cat "$work/purge.log"; fail "dpkg --purge"; }
check "purge removes /var/lib/mirrorscan and the token" [ ! -e "$root/var/lib/mirrorscan" ]
check "purge removes board.json" [ ! -e "$root/etc/mirrorscan/board.json" ]
check "purge removes the unit's enablement" [ ! -e "$root/etc/systemd/system/multi-user.target.wants/mirrorscand.service" ]
check "purge leaves the system user (Debian practice)" grep -q '^mirrorscan:' "$root/etc/passwd"
check "the running system's users and groups are untouched" \
  [ "$(cat /etc/passwd /etc/group | sha256sum)" = "$system_ids_before" ]

# --- 4. lintian -----------------------------------------------------------------------
for p in "${packages[@]}"; do
  echo "== lintian $p"
  if ! lintian --fail-on error --tag-display-limit 0 "${deb[$p]}" >"$work/lintian-$p.txt" 2>&1; then
    fail "lintian: errors in $p"
  fi
  sed 's/^/   /' "$work/lintian-$p.txt"
done

if ((failures > 0)); then
  echo "packages_test: $failures failures" >&2
  exit 1
fi
echo "packages_test: ${packages[*]} ($arch) pass"
