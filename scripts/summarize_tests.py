"""Adds up the three suites' results into one closing line: 'total: N passed, M failed'."""
import json
import pathlib
import sys
import xml.etree.ElementTree as ET

results = pathlib.Path(sys.argv[1])
passed = failed = skipped = 0
missing = []
for name in ("ctest.xml", "pytest.xml"):
    path = results / name
    if not path.exists():
        missing.append(name)
        continue
    root = ET.parse(path).getroot()
    suites = [root] if root.tag == "testsuite" else root.findall("testsuite")
    if sum(int(s.get("tests", 0)) for s in suites) == 0:
        print(f"surfmap: {name} holds no test results (the suite found no tests)")
        failed += 1
    for s in suites:
        tests = int(s.get("tests", 0))
        bad = int(s.get("failures", 0)) + int(s.get("errors", 0))
        skip = int(s.get("skipped", 0) or s.get("disabled", 0))
        passed += tests - bad - skip
        failed += bad
        skipped += skip
blender = results / "blender.json"
if blender.exists():
    b = json.loads(blender.read_text())
    passed += b["passed"]
    failed += b["failed"]
else:
    missing.append("blender.json")
for m in missing:
    print(f"surfmap: no results from {m} (that suite did not run to the end)")
    failed += 1
print(f"total: {passed} passed, {failed} failed" + (f", {skipped} skipped" if skipped else ""))
sys.exit(1 if failed else 0)
