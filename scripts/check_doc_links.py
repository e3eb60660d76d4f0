#!/usr/bin/env python3
"""Check that every relative link in README.md and docs/**/*.md resolves, anchors included (GitHub-style
heading slugs); links to outside the repository are reported too. Usage: scripts/check_doc_links.py [ROOT]."""
import re, os, sys, unicodedata
root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
files = [os.path.join(root, 'README.md')] + [os.path.join(dp, f) for dp, _, fs in os.walk(os.path.join(root, 'docs')) for f in fs if f.endswith('.md')]
def slug(h):
    h = h.strip().lower()
    h = re.sub(r'[^\w\- ]', '', h)   # GitHub: drop punctuation except - and _
    return h.replace(' ', '-')
def anchors(path):
    out = set(); inside = False; seen = {}
    for l in open(path, encoding='utf-8'):
        if l.startswith('```'): inside = not inside; continue
        if inside: continue
        m = re.match(r'^(#{1,6}) (.*)', l)
        if m:
            s = slug(m.group(2)); n = seen.get(s, 0); seen[s] = n + 1
            out.add(s if n == 0 else f'{s}-{n}')
    return out
bad = 0; n = 0
for f in files:
    text = open(f, encoding='utf-8').read()
    text = re.sub(r'```.*?```', '', text, flags=re.S)
    for m in re.finditer(r'\]\(([^)\s]+)\)', text):
        t = m.group(1)
        if re.match(r'[a-z]+://', t) or t.startswith('mailto:'): print('EXTERNAL', f, t); bad += 1; continue
        n += 1
        path, _, frag = t.partition('#')
        target = os.path.normpath(os.path.join(os.path.dirname(f), path)) if path else f
        if not os.path.exists(target): print('MISSING', f, t); bad += 1; continue
        if frag and target.endswith('.md') and frag not in anchors(target): print('ANCHOR', f, t); bad += 1
print(n, "links checked,", bad, "bad")
sys.exit(1 if bad else 0)
