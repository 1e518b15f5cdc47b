#!/usr/bin/env python3
"""Check the repository's documentation links.

For every *.md file under the root (not in build*/ folders, .git, node_modules or tests/fixtures/),
every relative link target must exist, and a '#anchor' must name a heading of the target file, by
GitHub's anchor rules (lower case, punctuation other than '-' and '_' removed, spaces to '-', '-1',
'-2', ... for repeated headings). For every source file under baker, runtime, formats, tools,
tests, shaders, fuzz, examples, exporters, viewer and integrations, every citation of the form
docs/<page>.md#<anchor>, README.md#<anchor>, ARCHITECTURE.md#<anchor> or
formats/CONVENTIONS.md#<anchor> (paths from the root; the anchor is optional) must resolve the same
way.

Usage: check-doc-links.py [--root DIR]. Prints each broken link as 'file:line: ...' and exits 1;
otherwise prints how many links and citations it checked and exits 0. Standard library only.
"""

import argparse
import os
import re
import sys
import urllib.parse

SOURCE_DIRS = ("baker", "runtime", "formats", "tools", "tests", "shaders", "fuzz", "examples",
               "exporters", "viewer", "integrations")
# Paths under the root that hold deliberately broken examples (the negative test's fixture).
EXCLUDED = ("tests/fixtures",)

FENCE = re.compile(r"^\s*(```|~~~)")
HEADING = re.compile(r"^ {0,3}(#{1,6})\s+(.*?)\s*#*\s*$")
HTML_ANCHOR = re.compile(r"<a\s+(?:name|id)\s*=\s*\"([^\"]+)\"", re.IGNORECASE)
INLINE_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*<?([^()\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
REF_LINK = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+\"[^\"]*\")?\s*$")
CODE_SPAN = re.compile(r"(`+)(.+?)\1", re.DOTALL)
CITATION = re.compile(
    r"(?<![\w./-])((?:docs/[\w.-]+\.md|README\.md|ARCHITECTURE\.md|formats/CONVENTIONS\.md)"
    r"(?:#[\w-]*)?)")


def github_anchor(text):
    """The anchor GitHub gives a heading's text (before the -1, -2 suffixes)."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)  # links: their text
    text = re.sub(r"<[^>]+>", "", text)  # inline HTML tags
    text = text.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def excluded(rel):
    rel = rel.replace(os.sep, "/")
    parts = rel.split("/")
    if any(p in (".git", "node_modules") or p.startswith("build") for p in parts[:-1]):
        return True
    return any(rel == e or rel.startswith(e + "/") for e in EXCLUDED)


_anchor_cache = {}


def anchors_of(path):
    """Every anchor a Markdown file defines."""
    if path in _anchor_cache:
        return _anchor_cache[path]
    anchors, seen = set(), {}
    in_fence = False
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            if FENCE.match(line):
                in_fence = not in_fence
                continue
            if in_fence:
                continue
            for name in HTML_ANCHOR.findall(line):
                anchors.add(name)
            m = HEADING.match(line)
            if m:
                base = github_anchor(m.group(2))
                n = seen.get(base, 0)
                seen[base] = n + 1
                anchors.add(base if n == 0 else "%s-%d" % (base, n))
    _anchor_cache[path] = anchors
    return anchors


def check_target(root, base_dir, target, where, errors):
    """Check one link target, relative to base_dir; append a message for a broken one."""
    path_part, _, anchor = target.partition("#")
    path_part = urllib.parse.unquote(path_part)
    anchor = urllib.parse.unquote(anchor)
    if path_part:
        if path_part.startswith("/"):
            full = os.path.normpath(os.path.join(root, path_part.lstrip("/")))
        else:
            full = os.path.normpath(os.path.join(base_dir, path_part))
        if not os.path.exists(full):
            errors.append("%s: link target '%s' does not exist" % (where, target))
            return
    else:
        full = where.rsplit(":", 1)[0]
        full = os.path.join(root, full)
    if anchor and full.endswith(".md") and os.path.isfile(full):
        if anchor not in anchors_of(full):
            errors.append("%s: '%s': no heading with anchor '#%s' in %s"
                          % (where, target, anchor, os.path.relpath(full, root)))


def blank(match):
    """A code span replaced by spaces, newlines kept, so line numbers stay right."""
    return re.sub(r"[^\n]", " ", match.group(0))


def check_markdown(root, rel, errors):
    full = os.path.join(root, rel)
    with open(full, encoding="utf-8", errors="replace") as f:
        lines = f.read().split("\n")
    # Drop fenced code blocks, then inline code spans, keeping the line structure.
    kept, in_fence = [], False
    for line in lines:
        if FENCE.match(line):
            in_fence = not in_fence
            kept.append("")
        else:
            kept.append("" if in_fence else line)
    text = CODE_SPAN.sub(blank, "\n".join(kept))
    count = 0
    targets = []
    for m in INLINE_LINK.finditer(text):
        targets.append((text.count("\n", 0, m.start(1)) + 1, m.group(1)))
    for i, line in enumerate(text.split("\n")):
        m = REF_LINK.match(line)
        if m:
            targets.append((i + 1, m.group(1)))
    for line_no, target in targets:
        if re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", target):  # http:, mailto:, ...
            continue
        count += 1
        check_target(root, os.path.dirname(full), target, "%s:%d" % (rel, line_no), errors)
    return count


def check_sources(root, rel, errors):
    full = os.path.join(root, rel)
    try:
        with open(full, "rb") as f:
            data = f.read()
    except OSError:
        return 0
    if b"\0" in data:
        return 0
    count = 0
    for i, line in enumerate(data.decode("utf-8", errors="replace").split("\n")):
        for m in CITATION.finditer(line):
            count += 1
            check_target(root, root, m.group(1), "%s:%d" % (rel, i + 1), errors)
    return count


def walk(root, top):
    for dirpath, dirnames, filenames in os.walk(os.path.join(root, top)):
        rel_dir = os.path.relpath(dirpath, root)
        dirnames[:] = sorted(d for d in dirnames
                             if not excluded(os.path.join(rel_dir, d, "x")))
        for name in sorted(filenames):
            rel = os.path.normpath(os.path.join(rel_dir, name))
            if not excluded(rel):
                yield rel


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--root", default=os.path.join(os.path.dirname(__file__), ".."),
                        help="the tree to check (default: this repository)")
    args = parser.parse_args()
    root = os.path.abspath(args.root)
    errors = []
    links = citations = 0
    for rel in walk(root, "."):
        if rel.endswith(".md"):
            links += check_markdown(root, rel, errors)
    for top in SOURCE_DIRS:
        if os.path.isdir(os.path.join(root, top)):
            for rel in walk(root, top):
                if not rel.endswith(".md"):
                    citations += check_sources(root, rel, errors)
    for e in errors:
        print(e)
    if errors:
        print("check-doc-links: %d broken of %d links and %d citations"
              % (len(errors), links, citations), file=sys.stderr)
        return 1
    print("check-doc-links: %d links in Markdown and %d citations in sources, all resolve"
          % (links, citations))
    return 0


if __name__ == "__main__":
    sys.exit(main())
