#!/usr/bin/python3
"""Every repository path and link in README.md and docs/*.md leads somewhere.

Checked, so a moved or renamed file cannot leave the manual pointing at nothing:
  - repository paths in `code` spans and fenced code blocks: a word whose first component is a
    top-level entry of the repository (core/..., scripts/bench-peers, tests/, CMakeLists.txt) must
    exist (a word with * or ? must match something);
  - Markdown links and images [text](target): a relative target must exist inside the repository, and
    a #fragment must name a heading of the target page (GitHub's anchors).
Every problem is listed (file, line, what), then the test fails. Usage: doc_links.py [SOURCE_DIR]
"""
import glob
import os
import re
import subprocess
import sys

CODE_SPAN = re.compile(r"`([^`\n]+)`")
LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
FENCE = re.compile(r"^\s*(```|~~~)")
WORD_TRIM = "()[]{},;:'\"<>"


def top_level_entries(root):
    """The repository's tracked top-level files and folders (a build folder is not one)."""
    try:
        files = subprocess.run(["git", "-C", root, "ls-files"], capture_output=True, text=True,
                               check=True).stdout.split()
        if files:
            return {f.split("/")[0] for f in files}
    except (OSError, subprocess.CalledProcessError):
        pass
    return {e for e in os.listdir(root) if not e.startswith("build")}


def slug(heading):
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link's text only
    text = text.strip().lower()
    text = "".join(c for c in text if c.isalnum() or c in " -_")
    return text.replace(" ", "-")


def scan(path):
    """(line number, text, in fenced code) per line, and the page's anchors."""
    lines, anchors, seen = [], set(), {}
    fenced = False
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            if FENCE.match(line):
                fenced = not fenced
                lines.append((number, line, True))
                continue
            lines.append((number, line, fenced))
            m = None if fenced else HEADING.match(line)
            if m:
                s = slug(m.group(2))
                anchors.add(s if s not in seen else f"{s}-{seen[s]}")
                seen[s] = seen.get(s, 0) + 1
    return lines, anchors


def path_words(text, tops):
    """The words of `text` that name a repository path."""
    for word in text.split():
        trimmed = None
        while trimmed != word:  # `(see docs/cli.md).`
            trimmed, word = word, word.strip(WORD_TRIM).rstrip(".")
        if "=" in word:  # --sparseleap=BIN, VAR=path
            word = word.split("=", 1)[1]
        if word.startswith("./"):
            word = word[2:]
        if not word or "…" in word or "..." in word:
            continue
        if word.split("/")[0] in tops and ("/" in word or word in tops):
            yield word


def exists(root, rel):
    full = os.path.join(root, rel)
    if any(c in rel for c in "*?"):
        return bool(glob.glob(full))
    return os.path.exists(full)


def check(root):
    tops = top_level_entries(root)
    pages = [os.path.join(root, "README.md")] + sorted(glob.glob(os.path.join(root, "docs", "*.md")))
    scanned = {os.path.realpath(p): scan(p) for p in pages}
    problems = []
    for page in pages:
        rel_page = os.path.relpath(page, root)
        lines, _ = scanned[os.path.realpath(page)]
        for number, line, fenced in lines:
            spans = [line] if fenced else CODE_SPAN.findall(line)
            for span in spans:
                for word in path_words(span, tops):
                    if not exists(root, word.rstrip("/")):
                        problems.append(f"{rel_page}:{number}: `{word}` does not exist")
            if fenced:
                continue
            for target in LINK.findall(CODE_SPAN.sub("", line)):
                if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # https:, mailto:
                    continue
                file_part, _, fragment = target.partition("#")
                dest = os.path.realpath(os.path.join(os.path.dirname(page), file_part)) if file_part else \
                    os.path.realpath(page)
                if os.path.commonpath([dest, os.path.realpath(root)]) != os.path.realpath(root):
                    problems.append(f"{rel_page}:{number}: link {target} leads outside the repository")
                    continue
                if not os.path.exists(dest):
                    problems.append(f"{rel_page}:{number}: link {target}: {os.path.relpath(dest, root)} does not exist")
                    continue
                if fragment and dest.endswith(".md"):
                    if dest not in scanned:
                        scanned[dest] = scan(dest)
                    if fragment not in scanned[dest][1]:
                        problems.append(f"{rel_page}:{number}: link {target}: no heading with the anchor #{fragment} "
                                        f"in {os.path.relpath(dest, root)}")
    return pages, problems


def main():
    root = os.path.realpath(sys.argv[1] if len(sys.argv) > 1 else
                            os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
    pages, problems = check(root)
    if problems:
        print("\n".join(problems))
        print(f"doc_links: {len(problems)} paths or links in README.md and docs/*.md lead nowhere (listed above): "
              "fix the page, or the path if a file moved", file=sys.stderr)
        return 1
    print(f"doc_links: every repository path and link in {len(pages)} pages exists")
    return 0


if __name__ == "__main__":
    sys.exit(main())
