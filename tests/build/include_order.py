#!/usr/bin/python3
"""Every arrow points down: a source file includes only from its own room or from rooms below it.

The rooms, lowest first, are listed in ROOMS; a file belongs to the room with the longest matching
prefix. Rooms on one line are siblings: neither may include the other. Test code (tests/) may include
anything and is not checked.

A control checks the same tree with one extra, made-up file in the lowest room that includes from the
highest, and requires exactly that violation to be found, so the check itself can fail.

Usage: include_order.py SOURCE_DIR
"""
import pathlib
import re
import sys

# Lowest first. Each entry is one level; the rooms of one level are siblings.
ROOMS = [
    ["core/util"],
    ["core/scene"],
    ["core/recon"],
    ["core/occupancy"],
    ["core/lists"],
    ["core/cast"],
    ["core/frame"],
    ["cache", "cache/stores"],
    ["cache/formats", "cache/synthetic", "cache/out_of_core", "cache/testing"],
    ["gl", "cuda"],
    ["apps"],
]
CHECKED = ("core", "cache", "gl", "cuda", "apps")
SUFFIXES = {".h", ".hpp", ".cpp", ".inc", ".cu", ".cuh"}
INCLUDE = re.compile(r'^[ \t]*#[ \t]*include[ \t]+"([^"]+)"', re.MULTILINE)


def room_of(path):
    """(level, room) of a repository path, or None when no room holds it."""
    best = None
    for level, rooms in enumerate(ROOMS):
        for room in rooms:
            if (path == room or path.startswith(room + "/")) and (best is None or len(room) > len(best[1])):
                best = (level, room)
    return best


def violations(files):
    """files: {repository path: text}. Returns one line per include that points up or sideways."""
    found = []
    for path, text in sorted(files.items()):
        own = room_of(path)
        if own is None:
            found.append(f"{path}: in no room (add its folder to ROOMS in {pathlib.Path(__file__).name})")
            continue
        for m in INCLUDE.finditer(text):
            target = m.group(1)
            if not target.startswith(tuple(r + "/" for r in CHECKED)):
                continue  # a system or third-party header
            theirs = room_of(target)
            if theirs is None or theirs[1] == own[1]:
                continue
            line = text.count("\n", 0, m.start()) + 1
            if theirs[0] > own[0]:
                found.append(f"{path}:{line}: includes {target}, from room {theirs[1]} above its own room {own[1]}")
            elif theirs[0] == own[0]:
                found.append(f"{path}:{line}: includes {target}, from the sibling room {theirs[1]} of {own[1]}")
    return found


def main(argv):
    if len(argv) != 1:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        return 2
    src = pathlib.Path(argv[0])
    files = {}
    for top in CHECKED:
        for p in (src / top).rglob("*"):
            if p.suffix in SUFFIXES and p.is_file():
                files[p.relative_to(src).as_posix()] = p.read_text(encoding="utf-8", errors="replace")
    if not files:
        print(f"include_order: no sources under {src}", file=sys.stderr)
        return 1

    probe = ROOMS[0][0] + "/include_order_probe.h"
    target = ROOMS[-1][0] + "/main.cpp"
    control = violations({**files, probe: f'#pragma once\n#include "{target}"\n'})
    if not any(v.startswith(probe + ":2:") for v in control):
        print(f"include_order: control failed: an include of {target} from {probe} was not reported", file=sys.stderr)
        return 1

    found = violations(files)
    for v in found:
        print(v, file=sys.stderr)
    if found:
        print(f"include_order: {len(found)} include(s) against the order of rooms (lowest first): "
              + " < ".join("|".join(level) for level in ROOMS), file=sys.stderr)
        return 1
    print(f"include_order: {len(files)} files, every include from its own room or one below "
          f"({len(ROOMS)} levels, control caught)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
