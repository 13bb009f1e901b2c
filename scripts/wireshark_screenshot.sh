#!/usr/bin/env bash
# The screenshot in docs/wireshark.md: Wireshark itself, under Xvfb, showing one command's
# whole path in a simulator capture (radio order -> joint commands -> done events).
#   bash scripts/wireshark_screenshot.sh [OUT.png]
# Needs Debian's wireshark-qt, xvfb, x11-apps (xwd), xdotool and imagemagick.
set -euo pipefail
out="${1:-docs/img/wireshark-path.png}"
cd "$(dirname "$0")/.."
work=$(mktemp -d)
trap 'kill ${ws:-} ${xv:-} 2>/dev/null || true; rm -rf "$work"' EXIT
rprs=${RPRS:-.venv/bin/rprs}
"$rprs" sim --robots 0,1,2 --duration 6 --seed 4 --can --load 1 --cpu ideal --no-progress \
  --pcap "$work/run.pcapng" > /dev/null
display=:97
Xvfb "$display" -screen 0 1600x1000x24 -nolisten tcp > /dev/null 2>&1 & xv=$!
sleep 1
export DISPLAY=$display HOME=$work XDG_CONFIG_HOME=$work/config
mkdir -p "$work/config/wireshark"
# no "welcome"/recent files, the packet list, details and bytes panes stacked
cat > "$work/config/wireshark/preferences" <<'PREFS'
gui.layout_type: 1
gui.column.format: "No.", "%m", "Time", "%t", "Protocol", "%p", "Length", "%L", "Info", "%i"
PREFS
wireshark -X "lua_script:$(pwd)/hil/wireshark/rprs.lua" -r "$work/run.pcapng" \
  -Y 'frame.number >= 238 && (rprs || rprs_can.msg matches "CMD|EVENT")' -g 238 \
  > "$work/ws.log" 2>&1 & ws=$!
win=
for _ in $(seq 60); do
  win=$(xdotool search --name "run.pcapng" 2>/dev/null | head -1) && [ -n "$win" ] && break
  sleep 1
done
sleep 3
xdotool windowmove "$win" 0 0 windowsize "$win" 1600 1000
sleep 2
# click the radio frame's line in the details pane, then View > Expand Subtrees (Shift+Right)
xdotool mousemove 90 413 click 1
sleep 1
xdotool key shift+Right
sleep 2
xwd -root -display "$display" -silent | /usr/bin/convert xwd:- "$out"
echo "wrote $out"
