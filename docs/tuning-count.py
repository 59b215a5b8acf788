#!/usr/bin/env python3
"""Count the estimator's constants that say their unit and how they were set.

Run from the repository root: `python3 docs/tuning-count.py` prints

    total: N
    with unit: N
    with reason: N

and `-v` adds one row per constant (`file:line NAME unit? reason?`), the
ones missing something marked.

What is counted. Every named `const` item under `estimator/src` (`const`,
`pub const`, `pub(crate) const`, and those inside `impl` blocks and the
`internal!` macro's blocks), except:

- items inside a `#[cfg(test)]` module (from that attribute's `mod` line
  to its closing brace);
- `const _` compile-time assertions (no value to set);
- consts local to a function body (indented 8 spaces or more, e.g.
  `blob::to_slice`'s `ZEROS`, three padding bytes);
- const generics (`<const N: usize>`) and `const fn`.

Variants of one constant under `#[cfg(...)]` (same file, same name) count
once, with the doc comment of whichever variant has one.

A constant's doc comment is the run of `///` lines right above it
(attribute lines `#[...]` in between are skipped).

"With unit": the doc comment holds a unit token, as a whole word: a
physical unit (`rad`, `rad/s`, `s`, `m`, `kg`, `Hz`, `1/s`, `1/s^2`, `bytes`,
`degrees`), or a dimensionless kind (`dimensionless`, `share`, `ratio`,
`relative`, `a count`, `count of`, `number of`, `how many`, `no unit`).
A bare count noun ("Measurements a half swing holds") does not count.

"With reason": the doc comment says how the value was set, by one of
these phrases (case-insensitive): `set by`, `physics`, `derived`,
`derivation`, `sweep`, `swept`, `seed` / `seeds`, `from the blob`,
`chosen`, `calibrated on`, `calibrated at`, `so that`, `because`,
`measured on`, `fixed by`, `compared`.

It is a token test, not a judgment: a doc comment can hold a token
without a real reason. The table in `docs/tuning.md` is the judgment, one
line per constant.
"""

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "estimator" / "src"

CONST = re.compile(r"^(\s*)(?:pub(?:\([a-z]+\))?\s+)?const\s+([A-Z_][A-Z0-9_]*)\s*:")
UNIT = re.compile(
    r"(?<![\w'`])(rad|rad/s|s|m|kg|Hz|1/s|1/s\^2|bytes|degrees)(?![\w'`])"
    r"|\b(dimensionless|share|ratio|relative|a count|count of|number of|how many|no unit)\b",
    re.IGNORECASE,
)
REASON = re.compile(
    r"\b(set by|physics|derived|derivation|sweep|swept|seeds?|from the blob|chosen"
    r"|calibrated on|calibrated at|so that|because|measured on|fixed by|compared)\b",
    re.IGNORECASE,
)


def test_spans(lines):
    """Line indexes inside `#[cfg(test)]` modules."""
    skip = set()
    i = 0
    while i < len(lines):
        if lines[i].strip() == "#[cfg(test)]" and i + 1 < len(lines) and re.match(
            r"\s*(pub(\([a-z]+\))?\s+)?mod\s", lines[i + 1]
        ):
            depth, j, opened = 0, i + 1, False
            while j < len(lines):
                depth += lines[j].count("{") - lines[j].count("}")
                opened = opened or "{" in lines[j]
                skip.add(j)
                if opened and depth <= 0:
                    break
                j += 1
            i = j
        i += 1
    return skip


def doc_above(lines, i):
    doc = []
    j = i - 1
    while j >= 0:
        s = lines[j].strip()
        if s.startswith("///"):
            doc.insert(0, s[3:].strip())
        elif s.startswith("#["):
            pass
        else:
            break
        j -= 1
    return " ".join(doc)


def constants():
    found = {}
    for path in sorted(SRC.rglob("*.rs")):
        lines = path.read_text().split("\n")
        skip = test_spans(lines)
        for i, line in enumerate(lines):
            m = CONST.match(line)
            if not m or m.group(2) == "_" or i in skip or len(m.group(1)) >= 8:
                continue
            key = (path.relative_to(ROOT).as_posix(), m.group(2))
            doc = doc_above(lines, i)
            if key in found:
                if doc and not found[key][1]:
                    found[key] = (found[key][0], doc)
                continue
            found[key] = (i + 1, doc)
    return found


def main():
    verbose = "-v" in sys.argv[1:]
    found = constants()
    n_unit = n_reason = 0
    rows = []
    for (path, name), (line, doc) in found.items():
        unit = bool(UNIT.search(doc))
        reason = bool(REASON.search(doc))
        n_unit += unit
        n_reason += reason
        mark = "" if unit and reason else "  <-"
        rows.append(
            f"{path}:{line} {name} unit={'y' if unit else 'n'} reason={'y' if reason else 'n'}{mark}"
        )
    if verbose:
        print("\n".join(rows))
    print(f"total: {len(found)}")
    print(f"with unit: {n_unit}")
    print(f"with reason: {n_reason}")


if __name__ == "__main__":
    main()
