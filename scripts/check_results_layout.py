#!/usr/bin/env python3
"""Check a results.h5 against the layout documented in docs/RESULTS.md.

How to run:  scripts/check_results_layout.py DIR/results.h5 [--doc docs/RESULTS.md]
                 [--expect walls,contact,grain-contact]
Needs h5py (pip install h5py, or apt install python3-h5py).

The tables of docs/RESULTS.md are the specification: every group, dataset and attribute in
the file must match a documented path (with NNNNNN, WALL, MOTION, AXIS, IJ, STAGE as
placeholders), with the documented shape (symbols N, E, G, C, R bound from the file itself,
consistently), dtype, `units` attribute and attribute set; every documented object whose
condition holds (`always`, or one named with --expect) must exist. Prints one line per
problem and exits 1 if there is any, else prints a summary and exits 0.
"""
import argparse
import os
import re
import sys

import h5py

DOC = os.path.normpath(
    os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "RESULTS.md")
)

# Placeholders of documented paths: what each may stand for in a real path.
PLACEHOLDERS = {
    "NNNNNN": r"(?P<frame>\d{6})",
    "WALL": r"[^/]+",
    "MOTION": r"[^/]+",
    "AXIS": r"[xyz]",
    "IJ": r"(xx|yy|zz|yz|xz|xy)",
    "STAGE": r"\d+_[^/]+",
}

DTYPES = {"f64": "float64", "u32": "uint32", "u64": "uint64"}


def cells(line):
    """The cells of a markdown table row, stripped, without the outer pipes."""
    return [c.strip() for c in line.strip().strip("|").split("|")]


def tables(text):
    """Every markdown table of `text` as (header, rows), rows as dicts by header."""
    out, lines = [], text.splitlines()
    i = 0
    while i < len(lines):
        if lines[i].lstrip().startswith("|") and i + 1 < len(lines) and re.match(
            r"^\s*\|[\s:|-]+\|\s*$", lines[i + 1]
        ):
            header = cells(lines[i])
            rows = []
            i += 2
            while i < len(lines) and lines[i].lstrip().startswith("|"):
                rows.append(dict(zip(header, cells(lines[i]))))
                i += 1
            out.append((header, rows))
        else:
            i += 1
    return out


def unquote(cell):
    cell = cell.strip()
    if cell.startswith("`") and cell.endswith("`"):
        cell = cell[1:-1]
    return cell


class Entry:
    """One documented object (a row of the layout table)."""

    def __init__(self, row):
        self.path = unquote(row["path"])
        self.kind = row["kind"]
        self.when = row["when"]
        self.units = unquote(row["units"])
        if self.units == '""':
            self.units = ""
        self.dtype = row["dtype"]
        shape = unquote(row["shape"]).strip()
        self.shape = None
        if shape:
            inner = shape.strip("()").strip()
            self.shape = [s.strip() for s in inner.split(",") if s.strip()]
        self.attrs = {}  # name -> (type, optional)
        for a in unquote(row["attributes"]).split(","):
            a = a.strip()
            if not a:
                continue
            name, typ = a.split(":")
            optional = typ.endswith("?")
            self.attrs[name.strip()] = (typ.strip().rstrip("?"), optional)
        pattern = re.escape(self.path)
        for key, regex in PLACEHOLDERS.items():
            pattern = pattern.replace(key, regex)
        self.regex = re.compile("^" + pattern + "$")
        self.concrete = not any(k in self.path for k in PLACEHOLDERS)
        self.matched = False


def load_doc(path):
    with open(path, encoding="utf-8") as f:
        text = f.read()
    entries, scopes = [], {}
    for header, rows in tables(text):
        if header[:2] == ["path", "kind"]:
            entries.extend(Entry(r) for r in rows)
        elif header[:1] == ["symbol"]:
            scopes.update({r["symbol"]: r["scope"] for r in rows})
    if not entries or not scopes:
        sys.exit(f"{path}: no layout table or no symbol table found")
    return entries, scopes


def dtype_ok(expected, actual):
    if expected == "str":
        return actual.kind in "SUO" and (
            actual.kind != "O" or h5py.check_string_dtype(actual) is not None
        )
    return str(actual) == DTYPES.get(expected, expected)


def attr_dtype_ok(expected, value):
    if expected == "str":
        return isinstance(value, (str, bytes))
    kind = getattr(value, "dtype", None)
    return kind is not None and str(kind) == DTYPES.get(expected, expected)


class Checker:
    def __init__(self, entries, scopes, expect):
        self.entries, self.scopes, self.expect = entries, scopes, expect
        self.bindings = {}  # (symbol, scope key) -> value
        self.problems = []
        self.objects = 0

    def problem(self, msg):
        self.problems.append(msg)

    def bind(self, symbol, value, frame, path):
        key = (symbol, frame if self.scopes.get(symbol) == "frame" else None)
        bound = self.bindings.setdefault(key, (value, path))
        if bound[0] != value:
            where = f" in frame {frame}" if key[1] is not None else ""
            return f"{symbol} = {value} here but {bound[0]} in {bound[1]}{where}"
        return None

    def shape_problem(self, entry, shape, frame, path):
        if len(entry.shape) != len(shape):
            return f"rank {len(shape)} {shape}, documented {tuple(entry.shape)}"
        for sym, n in zip(entry.shape, shape):
            if sym.isdigit():
                if int(sym) != n:
                    return f"shape {shape}, documented {tuple(entry.shape)}"
            elif sym in self.scopes:
                p = self.bind(sym, n, frame, path)
                if p:
                    return f"shape {shape}: {p}"
            else:
                return f"undocumented shape symbol {sym}"
        return None

    def object_problems(self, entry, obj, path, frame):
        """Problems of `obj` against `entry` (empty: it matches)."""
        out = []
        is_group = isinstance(obj, h5py.Group)
        if (entry.kind == "group") != is_group:
            return [f"is a {'group' if is_group else 'dataset'}, documented {entry.kind}"]
        if not is_group:
            if not dtype_ok(entry.dtype, obj.dtype):
                out.append(f"dtype {obj.dtype}, documented {entry.dtype}")
            units = obj.attrs.get("units")
            if isinstance(units, bytes):
                units = units.decode()
            if units != entry.units:
                out.append(f"units {units!r}, documented {entry.units!r}")
        for name in obj.attrs:
            # an attribute documented as `kind_K` stands for kind_0, kind_1, ...
            key = re.sub(r"_[0-9]+$", "_K", name)
            key = name if name in entry.attrs else key
            if key not in entry.attrs:
                out.append(f"undocumented attribute {name}")
            elif not attr_dtype_ok(entry.attrs[key][0], obj.attrs[name]):
                out.append(f"attribute {name} is not {entry.attrs[key][0]}")
        for name, (_, optional) in entry.attrs.items():
            if not optional and name not in obj.attrs:
                out.append(f"missing attribute {name}")
        return out

    def check(self, path, obj):
        self.objects += 1
        candidates = [e for e in self.entries if e.regex.match(path)]
        # A concrete path (e.g. /history/contact_energy) wins over a pattern.
        concrete = [e for e in candidates if e.concrete]
        candidates = concrete or candidates
        if not candidates:
            self.problem(f"{path}: not documented in docs/RESULTS.md")
            return
        m = candidates[0].regex.match(path)
        frame = m.groupdict().get("frame") if m else None
        # Patterns can overlap (a wall and a motion both named by the pattern NAME_force_x
        # match top_force_x): the object is documented if it fits any of them, and it
        # counts as present for each one it fits.
        first, fits = None, False
        for entry in candidates:
            probs = self.object_problems(entry, obj, path, frame)
            if not probs and entry.shape is not None and not isinstance(obj, h5py.Group):
                p = self.shape_problem(entry, obj.shape, frame, path)
                probs = [p] if p else []
            if probs:
                first = first or probs
            else:
                entry.matched = fits = True
        if not fits:
            candidates[0].matched = True  # present, if wrong: reported once, here
            for p in first:
                self.problem(f"{path}: {p}")

    def run(self, f):
        self.check("/", f)
        f.visititems(lambda name, obj: self.check("/" + name, obj))
        for e in self.entries:
            if e.matched:
                continue
            if e.when == "always" or e.when in self.expect:
                self.problem(f"{e.path}: documented ({e.when}) but not in the file")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file")
    ap.add_argument("--doc", default=DOC)
    ap.add_argument(
        "--expect",
        default="",
        help="comma-separated conditions that hold for this run (frames, walls, ...)",
    )
    args = ap.parse_args()
    entries, scopes = load_doc(args.doc)
    expect = {c.strip() for c in args.expect.split(",") if c.strip()}
    unknown = expect - {e.when for e in entries}
    if unknown:
        sys.exit(f"--expect: unknown condition(s) {sorted(unknown)}")
    checker = Checker(entries, scopes, expect)
    with h5py.File(args.file, "r") as f:
        checker.run(f)
    for p in checker.problems:
        print(p)
    if checker.problems:
        print(f"{args.file}: {len(checker.problems)} problem(s) against {args.doc}")
        sys.exit(1)
    sizes = ", ".join(
        f"{s}={v}" for (s, scope), (v, _) in sorted(checker.bindings.items()) if scope is None
    )
    print(f"{args.file}: {checker.objects} objects match {args.doc} ({sizes})")


if __name__ == "__main__":
    main()
