#!/usr/bin/env bash
# Run a command inside a small user-mode Linux (UML) VM that has a SocketCAN vcan0 interface.
#
#   scripts/vcan-vm.sh                      # runs: $RPRS_VM_PYTHON -m pytest -m vcan -q -n 0 --timeout 120 --timeout-method thread
#   scripts/vcan-vm.sh .venv/bin/pytest -k smoke -v
#   scripts/vcan-vm.sh --prepare            # only fetch/extract the UML kernel (cached)
#
# The guest's root filesystem is the host's own "/" (UML hostfs), so the command runs on the
# project's files and venv as they are; inside, the script loads can, can-raw, can-bcm and vcan
# from the UML kernel's own modules, creates vcan0 (MTU 72: classic CAN and CAN FD), exports
# RPRS_VCAN=1 and runs the command from the project root. Its exit status is this script's.
# Exit 125 means the VM itself could not be prepared or run. See docs/vcan.md.
#
# Settings (environment):
#   RPRS_VM_PYTHON   python used inside the VM (default .venv/bin/python, relative to the root)
#   RPRS_VM_SUITE    Debian suite whose user-mode-linux is used (default trixie)
#   RPRS_VM_MIRROR   Debian mirror (default http://deb.debian.org/debian)
#   RPRS_VM_CACHE    cache directory (default <project>/.cache/vcan-vm)
#   RPRS_VM_MEM      guest memory (default 512M)
#   RPRS_VM_TIMEOUT  seconds before the VM is killed (default 1800)
#   RPRS_VM_KEEP=1   keep the per-run directory (init script, kernel log) for debugging
# Exit status: the command's; 125 if the VM could not be prepared or started; 123 if it booted
# but this host's kernel cannot run its guest programs (the guest's init died at once).
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
CACHE=${RPRS_VM_CACHE:-$ROOT/.cache/vcan-vm}
SUITE=${RPRS_VM_SUITE:-trixie}
MIRROR=${RPRS_VM_MIRROR:-http://deb.debian.org/debian}
MEM=${RPRS_VM_MEM:-512M}
TIMEOUT=${RPRS_VM_TIMEOUT:-1800}
PY=${RPRS_VM_PYTHON:-.venv/bin/python}
KEYRING=/usr/share/keyrings/debian-archive-keyring.gpg
UMLDIR=$CACHE/uml-$SUITE
UML=$UMLDIR/linux

say() { printf 'vcan-vm: %s\n' "$*" >&2; }
die() { printf 'vcan-vm: FAILED: %s\n' "$*" >&2; exit 125; }

# ---------------------------------------------------------------- host checks
[ "$(uname -s)" = Linux ] && [ "$(uname -m)" = x86_64 ] \
  || die "virtualization unavailable: user-mode Linux needs an x86_64 Linux host (this is $(uname -sm))"
if [ -r /proc/sys/kernel/yama/ptrace_scope ] && [ "$(cat /proc/sys/kernel/yama/ptrace_scope)" = 3 ]; then
  die "virtualization unavailable: ptrace is disabled (kernel.yama.ptrace_scope=3); user-mode Linux needs it"
fi
for tool in apt-get dpkg-deb timeout; do
  command -v "$tool" >/dev/null || die "missing host tool '$tool' (a Debian/Ubuntu host is expected)"
done
HOSTPY=$(command -v python3 || true)
[ -n "$HOSTPY" ] || HOSTPY=$PY
if ! command -v ip >/dev/null; then
  if [ "$(id -u)" = 0 ]; then
    say "installing iproute2 on the host (the guest uses the host's 'ip')"
    { apt-get install -y -qq iproute2 || { apt-get update -qq && apt-get install -y -qq iproute2; }; } >/dev/null \
      || die "could not install iproute2"
  else
    die "no 'ip' on this host: run 'sudo apt-get install iproute2' (the guest uses the host's binaries)"
  fi
fi
IP=$(command -v ip)

mkdir -p "$CACHE"
# everything in the cache stays out of git, whatever the project's .gitignore says
[ -f "$CACHE/.gitignore" ] || printf '*\n' > "$CACHE/.gitignore"

# can-utils: candump, an independent reader of vcan0 that tests compare our CAN logs with. The
# host's own, if it has one; else, like patchelf, fetched from the host's apt sources and
# unpacked into the cache (never installed), and its bin/ goes on the guest's PATH. If it
# cannot be fetched, those tests skip and say so; nothing else needs it.
CANUTILS=
get_candump() {
  command -v candump >/dev/null && return 0
  local dir=$CACHE/can-utils
  if [ ! -x "$dir/usr/bin/candump" ]; then
    say "fetching can-utils from the host's own apt sources (candump, for the tests that compare logs with it; no install)"
    local d; d=$(mktemp -d "$CACHE/tmp.XXXXXX")
    if ! (cd "$d" && apt-get download -qq can-utils) >/dev/null 2>&1; then
      if [ "$(id -u)" = 0 ]; then apt-get update -qq >/dev/null 2>&1 || true; fi
      (cd "$d" && apt-get download -qq can-utils) >/dev/null 2>&1 || true
    fi
    if ls "$d"/can-utils_*.deb >/dev/null 2>&1; then
      rm -rf "$dir"; dpkg-deb -x "$d"/can-utils_*.deb "$dir"
    fi
    rm -rf "$d"
  fi
  if [ -x "$dir/usr/bin/candump" ]; then
    CANUTILS=$dir/usr/bin
  else
    say "could not fetch can-utils with apt-get download: the candump comparison will skip"
  fi
}
get_candump

# ---------------------------------------------------------------- prepare (cached)
uml_ok() { [ -f "$UMLDIR/READY" ] && "$UML" --version >/dev/null 2>&1; }

get_patchelf() {
  if command -v patchelf >/dev/null; then command -v patchelf; return; fi
  local pe=$CACHE/patchelf/usr/bin/patchelf
  if [ ! -x "$pe" ]; then
    say "fetching patchelf from the host's own apt sources (no install)"
    local d; d=$(mktemp -d "$CACHE/tmp.XXXXXX")
    if ! (cd "$d" && apt-get download -qq patchelf) >/dev/null 2>&1; then
      [ "$(id -u)" = 0 ] || die "could not fetch patchelf: run 'sudo apt-get update' or 'sudo apt-get install patchelf'"
      apt-get update -qq >/dev/null 2>&1 || true
      (cd "$d" && apt-get download -qq patchelf) >/dev/null 2>&1 || die "could not fetch patchelf with apt-get download"
    fi
    rm -rf "$CACHE/patchelf"; dpkg-deb -x "$d"/patchelf_*.deb "$CACHE/patchelf"; rm -rf "$d"
  fi
  echo "$pe"
}

prepare() {
  uml_ok && return 0
  say "preparing the user-mode Linux kernel from Debian $SUITE into $UMLDIR (once; cached)"
  [ -r "$KEYRING" ] || die "missing $KEYRING (apt-get install debian-archive-keyring)"
  local apt=$CACHE/apt-$SUITE
  mkdir -p "$apt/lists/partial" "$apt/cache/archives/partial" "$apt/debs"
  printf 'deb [signed-by=%s] %s %s main\n' "$KEYRING" "$MIRROR" "$SUITE" > "$apt/sources.list"
  # A private sources list, lists and cache: the host's apt state and packages are untouched.
  local -a o=(-o "Dir::Etc::sourcelist=$apt/sources.list" -o Dir::Etc::sourceparts=/dev/null
              -o "Dir::State::Lists=$apt/lists" -o "Dir::Cache=$apt/cache" -o APT::Get::List-Cleanup=0)
  [ "$(id -u)" = 0 ] && o+=(-o APT::Sandbox::User=root)
  local t0=$SECONDS
  apt-get "${o[@]}" -qq update >"$apt/update.log" 2>&1 \
    || die "apt-get update for Debian $SUITE failed: $(grep -E '^(E|Err):' "$apt/update.log" | head -1)"
  rm -f "$apt"/debs/*.deb
  (cd "$apt/debs" && apt-get "${o[@]}" -qq download user-mode-linux libc6) >"$apt/download.log" 2>&1 \
    || die "apt-get download user-mode-linux libc6 from $SUITE failed: $(grep -E '^E:' "$apt/download.log" | head -1)"
  local x; x=$(mktemp -d "$CACHE/tmp.XXXXXX")
  dpkg-deb -x "$apt"/debs/user-mode-linux_*.deb "$x/uml"
  dpkg-deb -x "$apt"/debs/libc6_*.deb "$x/libc"
  local kver; kver=$(ls "$x/uml/usr/lib/uml/modules")
  [ -n "$kver" ] && [ -d "$x/uml/usr/lib/uml/modules/$kver/kernel/net/can" ] \
    || die "this user-mode-linux package ships no CAN modules"
  rm -rf "$UMLDIR.new"; mkdir -p "$UMLDIR.new/modules" "$UMLDIR.new/lib"
  cp "$x/uml/usr/bin/linux.uml" "$UMLDIR.new/linux"
  local m=$x/uml/usr/lib/uml/modules/$kver
  (cd "$m" && cp --parents -r modules.dep modules.builtin kernel/net/can kernel/drivers/net/can "$UMLDIR.new/modules/")
  cp -a "$x/libc/usr/lib/x86_64-linux-gnu/." "$UMLDIR.new/lib/"
  rm -rf "$UMLDIR.new/lib/gconv"
  local uver lver
  uver=$(dpkg-deb -f "$apt"/debs/user-mode-linux_*.deb Version)
  lver=$(dpkg-deb -f "$apt"/debs/libc6_*.deb Version)
  rm -rf "$x" "$apt"
  local how=native
  if ! "$UMLDIR.new/linux" --version >/dev/null 2>&1; then
    # The host's glibc is older than the one linux.uml was built against (bookworm 2.36 vs 2.38+):
    # point the binary at the bundled glibc of the same suite (interpreter and rpath).
    local pe; pe=$(get_patchelf)
    "$pe" --set-interpreter "$UMLDIR/lib/ld-linux-x86-64.so.2" --set-rpath "$UMLDIR/lib" "$UMLDIR.new/linux" \
      || die "patchelf failed on linux.uml"
    how="patched to $SUITE's glibc $lver"
  fi
  rm -rf "$UMLDIR"; mv "$UMLDIR.new" "$UMLDIR"
  printf 'suite=%s\nuser-mode-linux=%s\nkernel=%s\nlibc6=%s\nbinary=%s\n' \
    "$SUITE" "$uver" "$kver" "$lver" "$how" > "$UMLDIR/READY"
  uml_ok || die "the prepared linux.uml does not run on this host: $("$UML" --version 2>&1 | head -1)"
  say "prepared user-mode-linux $uver (kernel $kver, $how) in $((SECONDS - t0)) s"
}

prepare
if [ "${1:-}" = --prepare ]; then cat "$UMLDIR/READY"; exit 0; fi

# ---------------------------------------------------------------- the run
if [ $# -eq 0 ]; then
  if [ ! -x "$ROOT/$PY" ] && [ ! -x "$PY" ]; then
    die "no python at '$PY' (create the venv: python3 -m venv .venv && .venv/bin/pip install -e '.[test]', or set RPRS_VM_PYTHON)"
  fi
  # a few tests: no xdist workers in the small VM; a test that hangs there fails in 120 s with
  # every thread's stack (pytest-timeout) rather than holding the VM to its whole timeout
  set -- "$PY" -m pytest -m vcan -q -n 0 --timeout 120 --timeout-method thread
fi
PYBIN=$(cd "$ROOT" && cd "$(dirname "$PY")" 2>/dev/null && pwd || true)

RUN=$(mktemp -d "$CACHE/run.XXXXXX")
UMLPID=
cleanup() {
  [ -n "$UMLPID" ] && kill "$UMLPID" 2>/dev/null || true
  if [ "${RPRS_VM_KEEP:-0}" = 1 ]; then say "kept $RUN"; else rm -rf "$RUN"; fi
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# The guest gets this shell's environment (so CI, PATH, locale ... are the same inside).
{
  for v in $(compgen -e); do
    case $v in BASH_*|SHLVL|PWD|OLDPWD|_|TERM) continue ;; esac
    printf 'export %s=%q\n' "$v" "${!v}"
  done
  printf 'export RPRS_VCAN=1\n'
  printf 'export PATH=%q\n' "${PYBIN:+$PYBIN:}$PATH:/usr/local/sbin:/usr/sbin:/sbin${CANUTILS:+:$CANUTILS}"
  # the guest's stdout is its console, a tty: no colour codes when ours is a pipe or a file
  [ -t 1 ] || printf 'export PY_COLORS=${PY_COLORS:-0} NO_COLOR=${NO_COLOR:-1}\n'
} > "$RUN/env"

cat > "$RUN/init" <<EOF
#!/bin/bash
# PID 1 of the UML guest (generated by scripts/vcan-vm.sh). / is the host's / through hostfs.
RUN=$(printf %q "$RUN"); ROOT=$(printf %q "$ROOT"); IP=$(printf %q "$IP"); HOSTPY=$(printf %q "$HOSTPY")
MODS=$(printf %q "$UMLDIR/modules")
export PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
poweroff() {
  sync
  "\$HOSTPY" -c 'import ctypes; ctypes.CDLL(None).reboot(0x4321FEDC)' 2>/dev/null
  echo o > /proc/sysrq-trigger; sleep 60
}
: > "\$RUN/booted"
mount -t proc proc /proc && mount -t sysfs sysfs /sys || { echo "vcan-vm(guest): mount failed"; poweroff; }
mountpoint -q /dev || mount -t devtmpfs devtmpfs /dev
mkdir -p /dev/shm /dev/pts
mount -t tmpfs tmpfs /dev/shm; mount -t devpts devpts /dev/pts
stty -onlcr 2>/dev/null
hostname rprs-vcan-vm 2>/dev/null
echo "vcan-vm(guest): kernel \$(uname -r) up; loading can, can-raw, can-bcm, vcan"
"\$HOSTPY" - "\$MODS" can-raw can-bcm vcan <<'PYEOF' || { echo "vcan-vm(guest): loading CAN modules failed"; poweroff; }
# insmod without kmod: finit_module(2) with the dependencies from modules.dep, in order
import ctypes, errno, os, sys
base, wanted = sys.argv[1], sys.argv[2:]
libc = ctypes.CDLL(None, use_errno=True)
deps = {}
with open(os.path.join(base, "modules.dep")) as f:
    for line in f:
        path, _, rest = line.partition(":")
        deps[os.path.basename(path)[:-3]] = (path, [os.path.basename(p)[:-3] for p in rest.split()])
done = set()
def load(name):
    if name in done:
        return
    done.add(name)
    if name not in deps:
        raise SystemExit(f"module {name} not in modules.dep")
    path, needs = deps[name]
    for dep in reversed(needs):
        load(dep)
    fd = os.open(os.path.join(base, path), os.O_RDONLY)
    try:
        if libc.syscall(313, fd, b"", 0) != 0 and ctypes.get_errno() != errno.EEXIST:
            raise SystemExit(f"finit_module({name}): {os.strerror(ctypes.get_errno())}")
    finally:
        os.close(fd)
for name in wanted:
    load(name)
PYEOF
"\$IP" link set lo up
"\$IP" link add dev vcan0 type vcan && "\$IP" link set vcan0 mtu 72 && "\$IP" link set up vcan0 \
  || { echo "vcan-vm(guest): creating vcan0 failed"; poweroff; }
echo "vcan-vm(guest): \$("\$IP" -brief link show vcan0)"
cd "\$ROOT" || poweroff
. "\$RUN/env"
echo "vcan-vm(guest): running in \$ROOT with RPRS_VCAN=1: $(printf '%q ' "$@")"
$(printf '%q ' "$@") </dev/null
rc=\$?
echo "\$rc" > "\$RUN/status.tmp" && mv "\$RUN/status.tmp" "\$RUN/status"
poweroff
EOF
chmod +x "$RUN/init"

# UML backs guest memory with a file in $TMPDIR, else /dev/shm: avoid a /dev/shm too small for it
UMLTMP=${TMPDIR:-}
if [ -z "$UMLTMP" ]; then
  shm_k=$(df -Pk /dev/shm 2>/dev/null | awk 'NR == 2 { print $4 }') || shm_k=
  mem_k=$(( $(numfmt --from=iec "$MEM") / 1024 )) || mem_k=0
  [ -n "$shm_k" ] && [ "$shm_k" -ge "$mem_k" ] || UMLTMP=/tmp
fi

say "booting user-mode Linux $(sed -n 's/^kernel=//p' "$UMLDIR/READY") (mem $MEM, root = host / via hostfs, timeout ${TIMEOUT}s)"
t0=$(date +%s.%N)
# con0: no input, output on our stdout; the kernel's own host-side messages go to uml.log.
${UMLTMP:+env TMPDIR="$UMLTMP"} timeout -k 10 "$TIMEOUT" "$UML" mem="$MEM" root=/dev/root rootfstype=hostfs rootflags=/ rw \
  init="$RUN/init" con0=null,fd:1 con=null ssl=null quiet loglevel=3 </dev/null 2>"$RUN/uml.log" &
UMLPID=$!
set +e; wait "$UMLPID"; vmrc=$?; set -e
UMLPID=
secs=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')

if [ ! -e "$RUN/booted" ]; then
  if [ "$vmrc" = 134 ]; then
    # The kernel booted and panicked on its init: the guest's first program (the host's bash,
    # through hostfs) died at once, before its first line. Seen on a host whose own kernel
    # (6.18, firecracker) does not run user-mode Linux's guests, with trixie's UML 6.12 and
    # bookworm's 6.1 alike: no VM can run the SocketCAN tests on this host.
    printf 'vcan-vm: UNAVAILABLE: user-mode Linux booted but its first guest program died at once (kernel panic: "Attempted to kill init"): this host (kernel %s) does not run UML guests\n' "$(uname -r)" >&2
    exit 123
  fi
  reason=$({ grep -v -e '^$' -e mmapper_init -e 'ubd device' "$RUN/uml.log" || true; } | tail -1)
  die "virtualization unavailable: user-mode Linux did not start (exit $vmrc${reason:+: $reason})"
fi
if [ ! -f "$RUN/status" ]; then
  [ "$vmrc" = 124 ] && why="killed after ${TIMEOUT}s (RPRS_VM_TIMEOUT)" || why="VM exited $vmrc before the command finished"
  sed 's/^/vcan-vm: uml.log: /' "$RUN/uml.log" | tail -20 >&2
  die "$why"
fi
rc=$(cat "$RUN/status")
say "VM finished in ${secs}s; command exit status $rc"
exit "$rc"
