#!/usr/bin/env bash
# Every relative link of the READMEs and docs/*.md leads somewhere: the file exists and, for a
# link into a Markdown page, its #anchor is one of the page's headings (GitHub's anchors).
# Lists file:line and the link for each one that does not resolve and exits non-zero when there
# is any. Python 3 standard library only; web links are not fetched.
set -euo pipefail
cd "$(dirname "$0")/.."

exec python3 - "$@" <<'PY'
import pathlib
import re
import sys

LINK = re.compile(r"\[(?:[^\[\]]|\[[^\]]*\])*\]\(([^()\s]+)(?:\s+\"[^\"]*\")?\)")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
FENCE = re.compile(r"^\s*(```|~~~)")


def pages():
    out = [pathlib.Path("README.md")]
    out += sorted(pathlib.Path("docs").glob("*.md"))
    out += sorted(p for p in pathlib.Path(".").glob("*/README.md")
                  if p.parts[0] not in {"vendor", "target"})
    return [p for p in out if p.is_file()]


def prose_lines(path):
    """(line number, line) outside code fences and indented code blocks."""
    fenced = False
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if FENCE.match(line):
            fenced = not fenced
            continue
        if fenced or line.startswith("    ") and not line.lstrip().startswith(("-", "*", "|")):
            continue
        yield n, line


def slug(text):
    """GitHub's anchor of a heading: the text without markup, lower case, punctuation dropped,
    spaces as hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)  # a link's text
    text = text.replace("`", "").replace("*", "").strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


anchors_of = {}


def anchors(path):
    if path not in anchors_of:
        seen, out = {}, set()
        for _, line in prose_lines(path):
            m = HEADING.match(line)
            if not m:
                continue
            a = slug(m.group(2))
            k = seen.get(a, 0)
            seen[a] = k + 1
            out.add(a if k == 0 else f"{a}-{k}")
        for m in re.finditer(r"<a\s+(?:name|id)=\"([^\"]+)\"", path.read_text(encoding="utf-8")):
            out.add(m.group(1))
        anchors_of[path] = out
    return anchors_of[path]


broken = []
for page in pages():
    for n, line in prose_lines(page):
        for m in LINK.finditer(line):
            target = m.group(1)
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.IGNORECASE):
                continue  # http:, https:, mailto:
            path, _, anchor = target.partition("#")
            dest = (page.parent / path).resolve() if path else page.resolve()
            if not dest.exists():
                broken.append(f"{page}:{n}: {target}: no such file")
                continue
            if anchor and dest.suffix == ".md":
                rel = pathlib.Path(dest).relative_to(pathlib.Path.cwd().resolve())
                if anchor not in anchors(rel):
                    broken.append(f"{page}:{n}: {target}: no heading #{anchor} in {rel}")

for b in broken:
    print(b)
if broken:
    print(f"\ndoc links: {len(broken)} link(s) do not resolve.", file=sys.stderr)
    sys.exit(1)
print("doc links: every relative link resolves")
PY
