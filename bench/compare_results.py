#!/usr/bin/env python3
"""Compares the `chunks` sections of two bakes' results JSON (bake --results).

Usage: compare_results.py OLD.json NEW.json

Prints "identical" when the sections are equal (the same bytes once parsed: verdicts,
stages, reasons, witnesses, notes, bounds, masks). Otherwise lists every bit whose verdict
differs, split into more proofs (undecided before, decided now) and bad differences (decided
before and undecided now, or 0 against 1), and counts the bits whose evidence alone differs.
Exit status: 0 identical or only more proofs, 1 any bad difference, 2 usage.
"""
import json
import sys


def bits(results):
    out = {}
    for chunk in results["chunks"]:
        for obj in chunk["objects"]:
            for group in obj.get("groups", []):
                for light in group.get("lights", []):
                    out[(chunk["chunk"], obj["element"], group["group"], light["light"])] = light
    return out


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        return 2
    old, new = (json.load(open(p)) for p in sys.argv[1:])
    if old["chunks"] == new["chunks"]:
        print("identical: %d bits" % len(bits(old)))
        return 0
    a, b = bits(old), bits(new)
    more, bad, evidence = [], [], 0
    for key in sorted(set(a) | set(b)):
        x, y = a.get(key), b.get(key)
        if x is None or y is None:
            bad.append((key, x and x["verdict"], y and y["verdict"]))
        elif x["verdict"] != y["verdict"]:
            (more if x["verdict"] == "undecided" else bad).append((key, x["verdict"], y["verdict"]))
        elif x != y:
            evidence += 1
    print("differ: %d bits, %d more proofs, %d bad, %d with other evidence only" % (len(a), len(more), len(bad), evidence))
    for key, x, y in bad[:50]:
        print("  BAD", key, x, "->", y)
    for key, x, y in more[:20]:
        print("  more", key, x, "->", y)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
