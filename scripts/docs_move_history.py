#!/usr/bin/env python3
"""Move session logs and dated sections out of docs/<topic>.md into docs/history/<topic>.md.

Reads each topic file as it was at BASE (git), so a re-run starts from the original text.
Items: ("H", prefix): the section whose heading line starts with prefix (up to the next heading
of the same or a higher level); ("HRE", regex): every heading matching regex, as H;
("R", start, end): the lines from the one starting with `start` up to (not including) the first
later line starting with `end` (end None: to the end of the file). Moved text is verbatim, in its
original order; a range that does not start with a heading is preceded by one line naming the
section it came from. Prints non-blank line counts.
"""
import os
import re
import subprocess
import sys
from pathlib import Path

BASE = next((a for a in sys.argv[1:] if not a.startswith("--")), "s27merge")
ROOT = Path(__file__).resolve().parent.parent
DOCS = Path(os.environ.get("DOCS_OUT", ROOT / "docs"))

SPECS = {
    "robustness": [
        ("H", "### Genus 0 (sliver"),
        ("H", "### High genus (9 to 24)"),
        ("HRE", r"^## (Session \d|Sweep, session|Maps onto real targets|Source side: tips|Held-out sweep)"),
    ],
    "handle_classes": [
        ("R", "**Measured** (`nice surfmap map A B --out o.obj --report r.json --quiet`,", "## Greedy pants decomposition",
         "## Pants decompositions with Fenchel"),
        ("R", "**On the genus-4 pair**", "**Verdicts without counting**"),
        ("R", "**Measured** (session 11, branch `pantscand`", "## Why the geometric classes failed"),
        ("H", "## Why the geometric classes failed"),
        ("R", "Measured (`surfmap map A B --out o.obj --report r.json --quiet`, Release, 2", "## Both directions agree"),
        ("H", "## Both directions agree (issue 14, session 11)"),
        ("H", "## Both directions, cheaply (issue 14, session 13)"),
        ("H", "## Bounds on the coarse copy (issue 19, session 16)"),
        ("R", "## The class does not depend on the base vertex (session 15)", None),
    ],
    "open_surfaces": [
        ("R", "**Fixed since: that inverse fold.**", "## Intake and validation"),
        ("H", "## Measurements"),
        ("H", "### Capped maps that fold"),
        ("H", "## What is left"),
        ("H", "## Session 26 (ui26)"),
    ],
    "benchmarks": [
        ("R", "Point location before/after (50k pair", "## Open surfaces (issue 16)"),
    ],
    "addon": [
        ("HRE", r"^## Session \d"),
    ],
    "verification": [
        ("H", "## Sliver images: folds on the target surface itself (session 15)"),
        ("H", "## Measured certificates (December 2026)"),
        ("H", "## A defect it found (fixed)"),
    ],
    "python": [
        ("H", "## Session 26: `start_surface_map` and `MapJob`"),
    ],
    "code_map": [
        ("H", "## Session 25: four review findings (tidy25)"),
    ],
}

# Names of outside publications in moved text are replaced by a description (docs/ cites nothing
# outside the repository); each replacement keeps the line count.
CITATIONS = [
    ("Murty's k-best assignments", "k-best assignments (ranked assignment enumeration)"),
    ("Bădoiu–Clarkson steps", "core-set steps"),
    ("Maskit's comparison", "the classical comparison of extremal length and length"),
    ("surface has that length: Yamada;", "surface has that length (a classical bound;"),
    ("Erickson–Whittlesey's maximum spanning cut tree T*)", "the greedy loops' maximum spanning cut tree T*)"),
    ("(Bobenko–Springborn allow", "(intrinsic Delaunay triangulations allow"),
]

HEADER = """# History: {title}

This file holds the session logs, dated sweeps, branch reports and before/after tables that were
appended to [docs/{topic}.md](../{topic}.md) up to session 26, moved here verbatim and in their
original order when that file was rewritten as a reference for the current design (session 27).
They record how the code got where it is: the measurements, the failures and the fixes, each with
the commit or the load it was measured at. Figures here describe the code of their session, not
necessarily today's; option names and defaults that still hold are stated in the topic file. The
only edits are the names of outside publications, replaced by a description of the idea.
"""


def heading_level(line):
    m = re.match(r"^(#{1,6}) ", line)
    return len(m.group(1)) if m else 0


def code_mask(lines):
    """True for lines inside fenced code blocks (their '#' lines are not headings)."""
    inside, mask = False, []
    for line in lines:
        if line.startswith("```"):
            mask.append(True)
            inside = not inside
            continue
        mask.append(inside)
    return mask


def find_unique(lines, prefix, mask, start=0, first=False):
    hits = [i for i in range(start, len(lines)) if lines[i].startswith(prefix) and not mask[i]]
    if first and hits:
        return hits[0]
    if len(hits) != 1:
        sys.exit(f"prefix {prefix!r}: {len(hits)} matches")
    return hits[0]


def section_end(lines, i, mask):
    lvl = heading_level(lines[i])
    for j in range(i + 1, len(lines)):
        if not mask[j] and 0 < heading_level(lines[j]) <= lvl:
            return j
    return len(lines)


def enclosing_heading(lines, i, mask):
    for j in range(i - 1, -1, -1):
        if not mask[j] and heading_level(lines[j]):
            return lines[j].lstrip("#").strip()
    return "the file's opening"


def nonblank(text):
    return sum(1 for l in text.splitlines() if l.strip())


# Pass 2 (`--pass2`): ranges moved later from the working tree's topic files, after the topic
# files were rewritten, so pass 1 (which writes the topic files from BASE) is not re-run over them.
# Each chunk goes into the history file in its original order (by its first line's position in
# BASE), preceded by one line naming the section it came from.
PASS2 = {
    "handle_classes": [
        ("R", '**Where "2.29 x the bound, mean D\' 3.44" came from**', "**One set of defaults.**"),
    ],
    "open_surfaces": [
        ("R", "Re-run in session 15 (2026-12-03", "## Intake and validation"),
    ],
}


def base_position(base_lines, line):
    try:
        return base_lines.index(line)
    except ValueError:
        return -1


def pass2():
    written = 0
    for topic, items in PASS2.items():
        base = subprocess.run(["git", "-C", str(ROOT), "show", f"{BASE}:docs/{topic}.md"],
                              capture_output=True, text=True, check=True).stdout.split("\n")
        tpath, hpath = DOCS / f"{topic}.md", DOCS / "history" / f"{topic}.md"
        lines = tpath.read_text().split("\n")
        hist = hpath.read_text().split("\n")
        before = nonblank(tpath.read_text()) + nonblank(hpath.read_text())
        mask = code_mask(lines)
        for item in items:
            i = find_unique(lines, item[1], mask)
            j = find_unique(lines, item[2], mask, i + 1, first=True)
            chunk = lines[i:j]
            while chunk and not chunk[-1].strip():
                chunk.pop()
            note = f"### From “{enclosing_heading(lines, i, mask)}”"
            pos = base_position(base, chunk[0])
            # history blocks start at headings; insert before the first whose BASE position is later
            hmask = code_mask(hist)
            at = len(hist)
            for k, l in enumerate(hist):
                if hmask[k] or not heading_level(l) or k == 0:
                    continue
                first = l
                if l.startswith("### From “"):
                    first = next((x for x in hist[k + 1:] if x.strip()), l)
                if base_position(base, first) > pos:
                    at = k
                    break
            hist[at:at] = [note, ""] + chunk + [""]
            del lines[i:j]
            mask = code_mask(lines)
            written += 1
        tpath.write_text(re.sub(r"\n{3,}", "\n\n", "\n".join(lines)))
        hpath.write_text(re.sub(r"\n{3,}", "\n\n", "\n".join(hist)))
        after = nonblank(tpath.read_text()) + nonblank(hpath.read_text())
        print(f"{topic:16s} pass 2: non-blank {before} -> {after} ({len(items)} note lines)")
    return written


def main():
    if "--pass2" in sys.argv:
        pass2()
        return
    total_before = total_after = written = 0
    for topic, items in SPECS.items():
        text = subprocess.run(["git", "-C", str(ROOT), "show", f"{BASE}:docs/{topic}.md"],
                              capture_output=True, text=True, check=True).stdout
        lines = text.split("\n")
        mask = code_mask(lines)
        ranges = []
        for item in items:
            if item[0] == "H":
                i = find_unique(lines, item[1], mask)
                ranges.append((i, section_end(lines, i, mask)))
            elif item[0] == "HRE":
                for i, l in enumerate(lines):
                    if not mask[i] and re.match(item[1], l):
                        ranges.append((i, section_end(lines, i, mask)))
            else:
                within = find_unique(lines, item[3], mask) if len(item) > 3 else 0
                i = find_unique(lines, item[1], mask, within, first=len(item) > 3)
                if item[2] is None:
                    j = len(lines)
                else:
                    j = find_unique(lines, item[2], mask, i + 1, first=True)
                ranges.append((i, j))
        ranges.sort()
        merged = []
        for a, b in ranges:  # a section inside an earlier one moves with it
            if merged and a < merged[-1][1]:
                merged[-1] = (merged[-1][0], max(b, merged[-1][1]))
            else:
                merged.append((a, b))
        moved, kept, last = [], [], 0
        for a, b in merged:
            kept.extend(lines[last:a])
            chunk = lines[a:b]
            while chunk and not chunk[-1].strip():
                chunk.pop()
            if not heading_level(chunk[0]):
                note = f"### From “{enclosing_heading(lines, a, mask)}”"
                moved.append([note, ""] + chunk)
                written += 1
            else:
                moved.append(chunk)
            last = b
        kept.extend(lines[last:])
        title = lines[0].lstrip("#").strip()
        header = HEADER.format(title=title, topic=topic)
        written += nonblank(header)
        body = "\n\n".join("\n".join(c) for c in moved)
        for old, new in CITATIONS:
            body = body.replace(old, new)
        hist = header + "\n" + body + "\n"
        kept_text = re.sub(r"\n{3,}", "\n\n", "\n".join(kept))
        (DOCS / "history").mkdir(parents=True, exist_ok=True)
        (DOCS / "history" / f"{topic}.md").write_text(hist)
        (DOCS / f"{topic}.md").write_text(kept_text)
        b_, k_, h_ = nonblank(text), nonblank(kept_text), nonblank(hist)
        total_before += b_
        total_after += k_ + h_
        print(f"{topic:16s} before {b_:5d}  topic {k_:5d}  history {h_:5d}  "
              f"(lines: {len(lines)} -> {len(kept_text.splitlines())} + {len(hist.splitlines())})")
    print(f"non-blank: before {total_before}, after {total_after}, written {written}, "
          f"check {'OK' if total_after == total_before + written else 'MISMATCH'}")


if __name__ == "__main__":
    main()
