#!/usr/bin/env bash
# Checks that a slamkit report.html renders in a real browser with every image loaded.
#
#   scripts/check_report_html.sh REPORT.html [--install]
#
# Renders the page in headless Chromium (Debian's `chromium` package; with --install it is
# installed with apt-get when missing), dumps the DOM after layout, and reads back a marker
# that a small inline script adds: the number of <img> elements and how many of them decoded
# (complete with a natural width > 0). Also takes a screenshot next to the report
# (report.png) and checks it is not blank. Exit status 0: all images loaded; 1: some did not
# or the page did not render; 77: no Chromium (skipped).
set -euo pipefail

report="${1:?usage: $0 REPORT.html [--install]}"
install="${2:-}"
[ -f "$report" ] || { echo "no such file: $report" >&2; exit 1; }

find_chromium() {
    command -v chromium || command -v chromium-browser || command -v google-chrome || true
}
browser="$(find_chromium)"
if [ -z "$browser" ] && [ "$install" = "--install" ]; then
    apt-get install -y chromium >/dev/null
    browser="$(find_chromium)"
fi
if [ -z "$browser" ]; then
    echo "skipped: chromium not installed (apt-get install -y chromium)" >&2
    exit 77
fi

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
# A copy of the page with a probe appended: after load, it writes the image counts into the
# DOM, where --dump-dom can read them.
cp "$report" "$work/page.html"
cat >>"$work/page.html" <<'EOF'
<script>
window.addEventListener("load", function () {
  var imgs = Array.prototype.slice.call(document.images);
  var ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;
  var probe = document.createElement("pre");
  probe.id = "slamkit-probe";
  probe.textContent = "IMAGES " + imgs.length + " LOADED " + ok;
  document.body.appendChild(probe);
});
</script>
EOF
flags=(--headless --no-sandbox --disable-gpu --disable-background-networking --disable-quic
       --no-first-run --disable-component-update --disable-sync --disable-dev-shm-usage --user-data-dir="$work/profile" --virtual-time-budget=5000)
"$browser" "${flags[@]}" --dump-dom "file://$work/page.html" >"$work/dom.html" 2>"$work/log.txt" || {
    echo "chromium failed:" >&2; tail -5 "$work/log.txt" >&2; exit 1; }
probe="$(grep -o 'IMAGES [0-9]* LOADED [0-9]*' "$work/dom.html" || true)"
if [ -z "$probe" ]; then
    echo "FAIL: the page did not finish loading (no probe in the DOM)" >&2
    exit 1
fi
read -r _ total _ loaded <<<"$probe"
shot="$(dirname "$report")/report.png"
"$browser" "${flags[@]}" --window-size=1400,2000 --screenshot="$shot" "file://$(realpath "$report")" \
    >/dev/null 2>&1 || true
echo "$report: $loaded of $total images loaded; screenshot $shot"
if [ "$total" -eq 0 ] || [ "$loaded" -ne "$total" ]; then
    echo "FAIL: images missing" >&2
    exit 1
fi
if [ ! -s "$shot" ]; then
    echo "FAIL: no screenshot" >&2
    exit 1
fi
# A blank page compresses to almost nothing; maps and plots do not.
size=$(stat -c %s "$shot")
if [ "$size" -lt 20000 ]; then
    echo "FAIL: screenshot looks blank ($size bytes)" >&2
    exit 1
fi
echo "OK"
