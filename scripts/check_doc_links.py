#!/usr/bin/env python3
"""Check that every relative link in README.md and docs/**/*.md resolves, anchors included (GitHub-style
heading slugs); links to outside the repository are reported too. Also checks the sections that code
comments, docstrings and help texts cite by name, as docs/<topic>.md "Heading" or
docs/history/<topic>.md "Heading" (a name may run on over comment lines): some heading of that file
must begin with the name (case, backquotes and line breaks aside). The docs' own citations of
another file's section, as `<file>.md "Heading"` or `[<file>.md](<file>.md) "Heading"`, are checked
the same way (not in docs/history/, whose logs keep the names they were written with). Usage: scripts/check_doc_links.py [ROOT]."""
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
CODE_DIRS = ('native', 'addon', 'scripts', 'bench', 'blender_tests', 'samples')
CODE_EXT = ('.cpp', '.h', '.hpp', '.py', '.sh', '.txt', '.cmake', '.toml')
CITE = re.compile(r'docs/((?:history/)?[a-z_0-9]+\.md),?((?:\s+\\?"[^"\\]{2,120}\\?")(?:[\s,;]*(?:and|or)?\s*\\?"[^"\\]{2,120}\\?")*)')
NAME = re.compile(r'\\?"([^"\\]{2,120})\\?"')
def headings(path):
    out = []; inside = False
    for l in open(path, encoding='utf-8'):
        if l.startswith('```'): inside = not inside; continue
        m = None if inside else re.match(r'^#{1,6} (.*)', l)
        if m: out.append(norm(m.group(1)))
    return out
def norm(name):
    return ' '.join(name.replace('`', '').split()).lower()
def flatten(text):
    """The file as one line, comment markers of continuation lines dropped ('// ', '/// ', '# ',
    '#: ', ' * '), with the offset each line starts at."""
    flat, starts = [], []; pos = 0
    for i, l in enumerate(text.split('\n')):
        if i: l = ' ' + re.sub(r'^\s*(?:///?|#:?|\*(?!\*))?\s?', '', l)
        starts.append(pos); flat.append(l); pos += len(l)
    return ''.join(flat), starts
cites = 0
for d in CODE_DIRS:
    for dp, _, fs in os.walk(os.path.join(root, d)):
        for fn in sorted(fs):
            if not fn.endswith(CODE_EXT): continue
            p = os.path.join(dp, fn)
            flat, starts = flatten(open(p, encoding='utf-8', errors='replace').read())
            for m in CITE.finditer(flat):
                line = sum(1 for o in starts if o <= m.start())
                target = os.path.join(root, 'docs', m.group(1))
                heads = headings(target) if os.path.exists(target) else []
                for nm in NAME.finditer(m.group(2)):
                    cites += 1
                    name = norm(nm.group(1))
                    if not any(h.startswith(name) for h in heads):
                        print('SECTION', f'{os.path.relpath(p, root)}:{line}', f'docs/{m.group(1)}', f'"{nm.group(1).strip()}"')
                        bad += 1
DOC_CITE = re.compile(r'(?<![\w/])(?:docs/)?((?:history/)?[a-z_0-9]+\.md)\]?(?:\([^)\s]*\))?,?\s+"([^"]{2,160})"')
doc_cites = 0
for f in files:
    if os.sep + 'history' + os.sep in f: continue   # the logs keep the names they were written with
    text = open(f, encoding='utf-8').read()
    here = os.path.dirname(f)
    for m in DOC_CITE.finditer(text):
        doc = m.group(1)
        target = next((t for t in (os.path.normpath(os.path.join(here, doc)), os.path.join(root, 'docs', doc))
                       if os.path.exists(t)), None)
        if target is None: continue   # a file named in passing, not a docs file
        doc_cites += 1
        if not any(h.startswith(norm(m.group(2))) for h in headings(target)):
            print('SECTION', f'{os.path.relpath(f, root)}:{text[:m.start()].count(chr(10)) + 1}', doc, f'"{" ".join(m.group(2).split())}"')
            bad += 1
print(n, "links checked,", cites, "sections cited from code,", doc_cites, "from the docs,", bad, "bad")
sys.exit(1 if bad else 0)
