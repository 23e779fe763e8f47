#!/usr/bin/env bash
# The project's files speak of the project as it is: no narrative of its own development
# (sessions, rounds, issue numbers, "previously", "no longer", ...) in the READMEs, docs/*.md,
# source comments, test names or CLI output. Lists file:line and the wording for each hit and
# exits non-zero when there is any. Python 3 standard library only.
#
# Searched: README.md, docs/*.md, each crate's README.md, and the *.rs, *.py and *.sh files under
# math, eval, msgs, io, nodes, cli, benches, tests, bags and fuzz (the fuzz targets and examples;
# not its corpora: seeds, regressions, dict). Never vendor/ or target/.
set -euo pipefail
cd "$(dirname "$0")/.."

exec python3 - "$@" <<'PY'
import bisect
import pathlib
import re
import sys

ROOTS = ["math", "eval", "msgs", "io", "nodes", "cli", "benches", "tests", "bags", "fuzz"]
SOURCE_SUFFIXES = {".rs", ".py", ".sh"}
# Never searched: vendored crates, build output, Python environments, fuzz corpora.
SKIP_DIRS = {"vendor", "target", "venv", ".venv", "__pycache__", "node_modules",
             "seeds", "regressions", "corpus", "artifacts", "dict"}

# (what it catches, pattern). Case-insensitive. Where a word has a technical meaning too, the
# pattern says which use it catches (context), rather than an allow-list of files or lines.
PATTERNS = [
    ("an issue number", r"\bissues?\s+#?\d+"),
    # A session of development; a DDS, ROS, RTPS, SSH, TLS, HTTP, test or debug session is a
    # technical one and is not caught.
    ("a development session",
     r"(?<!dds )(?<!ros )(?<!ros 2 )(?<!ros2 )(?<!rtps )(?<!ssh )(?<!tls )(?<!http )"
     r"(?<!test )(?<!debug )(?<!login )(?<!user )(?<!shell )\bsessions?\b(?!\s+(?:id|key|token)\b)"),
    ("a round of development", r"\bround\s+\d+\b|\brounds?\s+of\s+development\b"),
    ("history wording", r"\bpreviously\b"),
    # "no longer than" compares lengths.
    ("history wording", r"\bno\s+longer\b(?!\s+than\b)"),
    # "used to be" as history; "is used to be sure" (passive) is not caught.
    ("history wording", r"(?<!is )(?<!are )(?<!be )(?<!been )(?<!being )\bused\s+to\s+be\b"),
    ("history wording", r"\bwe\s+tried\b"),
    ("a pull request", r"\bthis\s+(?:PR|pull\s+request)\b"),
    ("a development branch", r"\bmain\s+at\s+[0-9a-f]{7,40}\b|\bbranch\s+point\b"
                              r"|\b(?:on\s+)?this\s+branch's\b|\bon\s+this\s+branch\b"),
    ("a development brief", r"\bthe\s+brief(?:'s)?\b"),
    ("the issue as a source", r"\b(?:the|this)\s+issue(?:'s)?\b"),
    ("a merge as history", r"\b(?:after|before|since)\s+the\s+merge\b"),
]
COMPILED = [(what, re.compile(p, re.IGNORECASE)) for what, p in PATTERNS]

def files():
    out = [pathlib.Path("README.md")]
    out += sorted(pathlib.Path("docs").glob("*.md"))
    for root in ROOTS:
        base = pathlib.Path(root)
        if not base.is_dir():
            continue
        readme = base / "README.md"
        if readme.is_file():
            out.append(readme)
        for p in sorted(base.rglob("*")):
            if p.suffix in SOURCE_SUFFIXES and p.is_file() and not (SKIP_DIRS & set(p.parts)):
                out.append(p)
    return [p for p in out if p.is_file()]

CODE_NEXT = re.compile(r"//|/\*|\bb?r#*\"|\"|'")
CHAR_LITERAL = re.compile(r"'(?:\\(?:u\{[0-9a-fA-F]+\}|x[0-9a-fA-F]{2}|.)|[^\\'])'")
STRING_NEXT = re.compile(r'\\.?|"')
BLOCK_NEXT = re.compile(r"/\*|\*/")


def rust_prose(lines):
    """Each line's comments and string literals, the code between them left out: identifiers
    are not prose (a variable may be called `session`), and history wording lives in comments,
    doc comments, messages and CLI output."""
    out, state, end_raw, depth = [], "code", "", 0
    for line in lines:
        keep, i, n = [], 0, len(line)
        while i < n:
            if state == "code":
                m = CODE_NEXT.search(line, i)
                if not m:
                    break
                tok, i = m.group(0), m.end()
                if tok == "//":
                    keep.append(line[i:].lstrip("/!"))
                    break
                if tok == "/*":
                    state, depth = "block", 1
                elif tok == "'":
                    c = CHAR_LITERAL.match(line, m.start())
                    i = c.end() if c else i
                elif tok == '"':
                    state = "string"
                else:  # a raw string: r"...", r#"..."#, br"..."
                    state, end_raw = "raw", '"' + "#" * tok.count("#")
            elif state == "block":
                m = BLOCK_NEXT.search(line, i)
                if not m:
                    keep.append(line[i:])
                    break
                keep.append(line[i:m.start()])
                i = m.end()
                depth += 1 if m.group(0) == "/*" else -1
                if depth == 0:
                    state = "code"
                    keep.append(" ")
            elif state == "string":
                m = STRING_NEXT.search(line, i)
                if not m:
                    keep.append(line[i:])
                    break
                keep.append(line[i:m.start()] + " ")
                i = m.end()
                if m.group(0) == '"':
                    state = "code"
            else:  # raw string
                j = line.find(end_raw, i)
                if j < 0:
                    keep.append(line[i:])
                    break
                keep.append(line[i:j] + " ")
                i, state = j + len(end_raw), "code"
        out.append("".join(keep))
    return out


def script_prose(lines):
    """Each line's comments and quoted strings (Python, shell), the code left out."""
    out = []
    for line in lines:
        keep, quote, i = [], None, 0
        while i < len(line):
            c = line[i]
            if quote:
                if c == "\\":
                    i += 2
                    continue
                if c == quote:
                    quote = None
                    keep.append(" ")
                else:
                    keep.append(c)
            elif c in "\"'":
                quote = c
            elif c == "#" and (i == 0 or line[i - 1] in " \t"):
                keep.append(line[i + 1:])
                break
            i += 1
        out.append("".join(keep))
    return out


# The lines joined by a space (without indentation and Markdown quote marks), so that wording
# broken across two lines of a paragraph or comment is found too; a hit is reported at the line
# where it starts.
hits = []
for path in files():
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError:
        continue
    if path.suffix == ".rs":
        prose = rust_prose(lines)
    elif path.suffix in (".py", ".sh"):
        prose = script_prose(lines)
    else:
        prose = [re.sub(r"^\s*>?\s*", "", line) for line in lines]
    starts, offset = [], 0
    for body in prose:
        starts.append(offset)
        offset += len(body.strip()) + 1
    text = " ".join(body.strip() for body in prose)
    found = {}
    for what, rx in COMPILED:
        for m in rx.finditer(text):
            lineno = bisect.bisect_right(starts, m.start())
            found.setdefault(lineno, (what, m.group(0)))
    for lineno in sorted(found):
        what, wording = found[lineno]
        hits.append(f"{path}:{lineno}: {what}: \"{wording}\": {lines[lineno - 1].strip()[:160]}")

for hit in hits:
    print(hit)
if hits:
    print(f"\nhistory wording: {len(hits)} line(s). The files speak of the project as it is: say what "
          "the code does and why, with today's figures and the commands that reproduce them, "
          "without the sessions, issues or changes that led there.", file=sys.stderr)
    sys.exit(1)
print("history wording: none")
PY
