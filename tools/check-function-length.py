#!/usr/bin/env python3
"""Fails when a function in the libraries or the tools is longer than the limit.

ARCHITECTURE.md#where-a-new-thing-goes keeps each function to one job; this check holds `baker/`,
`runtime/`, `formats/`, `viewer/`, `exporters/` and `tools/` to at most LIMIT lines per function,
counted from the line of its name (the identifier before its parameter list) to its closing brace,
inclusive. Lambdas, and the methods of a class local to a function, count as part of the function
they are written in. A function is named as written (`GltfLoader::loadPrimitive`), with its
enclosing classes in front when it is defined inside its class (`Renderer::Impl::record`). Tests,
fuzz targets and examples are not held to it.

Functions that were already longer when the limit came in are listed, with their length, in
tools/function-length-allowlist.txt: a listed function may not grow, and its line goes when it
is split. So the check fails when
  - a function that is not listed is over the limit;
  - a listed function is longer than its listed length;
  - a listed function no longer exists or is now within the limit (remove its line).
A name defined more than once in one file (overloads) is matched by length: the longest
definition over the limit is held to the longest listed length, the next to the next, and so on.
A listed function that has shrunk but is still over the limit gets a note (not a failure): lower
its listed length so that it cannot grow back.

    tools/check-function-length.py [--limit N] [--root DIR] [--list N]
                                   [--allowlist FILE] [--write-allowlist]

Prints each problem as `file:line: message` and exits 1; otherwise prints a summary and exits
0. `--list N` prints the N longest functions either way. `--write-allowlist` rewrites the list
from the current tree. The list holds for the default limit: with another `--limit` it is not
used unless `--allowlist` names it.

The C++ is read by a small scanner of its own (no dependency beyond python3): comments, string
and character literals (raw strings included) and preprocessor lines are blanked, then braces
are walked with a stack of scopes (namespace, class/struct/union, extern "C"); a `{` at scope
level whose declaration has a parameter list is a function body, anything else at scope level
(enum, initializer, lambda assigned to a variable) is skipped whole.
"""
import argparse
import collections
import pathlib
import re
import sys

FOLDERS = ["baker", "runtime", "formats", "viewer", "exporters", "tools"]
SUFFIXES = {".cpp", ".cc", ".cxx", ".hpp", ".hh", ".h", ".hxx", ".inl", ".ipp"}
LIMIT = 80
ALLOWLIST = pathlib.Path("tools") / "function-length-allowlist.txt"
ALLOWLIST_HEADER = f"""\
# Functions longer than the limit of tools/check-function-length.py ({LIMIT} lines) that predate the
# limit: `path name lines`. Each may not grow past its listed length; when one is split to
# within the limit, remove its line (the check fails on a stale line). Regenerate with
# tools/check-function-length.py --write-allowlist only to take lines out, never to let one grow.
"""

# --- blanking: comments, literals and preprocessor lines become spaces, newlines stay ---------

IDENT_CHARS = set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_")
RAW_PREFIXES = {"R", "u8R", "uR", "UR", "LR"}


def _blank(chars, start, end):
    for k in range(start, end):
        if chars[k] != "\n":
            chars[k] = " "


def _skip_quoted(text, i, quote, stop_at_newline):
    """Index after the literal that opens at text[i] (its quote)."""
    n = len(text)
    i += 1
    while i < n:
        c = text[i]
        if c == "\\":
            i += 2
            continue
        if c == quote:
            return i + 1
        if c == "\n" and stop_at_newline:
            return i
        i += 1
    return n


def _identifier_run_before(text, i):
    """The run of identifier characters that ends just before text[i]."""
    j = i
    while j > 0 and (text[j - 1] in IDENT_CHARS or text[j - 1] == "."):
        j -= 1
    return text[j:i], j


def blank(text):
    """text with comments, literals and preprocessor lines replaced by spaces (newlines kept)."""
    chars = list(text)
    n = len(text)
    i = 0
    line_start = True  # only whitespace since the last newline
    while i < n:
        c = text[i]
        nxt = text[i + 1] if i + 1 < n else ""
        if c == "\n":
            line_start = True
            i += 1
            continue
        if c in " \t\r\f\v":
            i += 1
            continue
        if c == "#" and line_start:
            end = _directive_end(text, i)
            _blank(chars, i, end)
            i = end
            continue
        line_start = False
        if c == "/" and nxt == "/":
            end = _line_comment_end(text, i)
        elif c == "/" and nxt == "*":
            found = text.find("*/", i + 2)
            end = n if found < 0 else found + 2
        elif c == '"':
            run, run_start = _identifier_run_before(text, i)
            if run in RAW_PREFIXES and (run_start == 0 or text[run_start - 1] not in IDENT_CHARS):
                end = _raw_string_end(text, i)
                i = run_start
            else:
                end = _skip_quoted(text, i, '"', False)
        elif c == "'":
            run, _ = _identifier_run_before(text, i)
            if run and run[0].isdigit():  # digit separator: 1'000'000
                i += 1
                continue
            end = _skip_quoted(text, i, "'", False)
        else:
            i += 1
            continue
        _blank(chars, i, end)
        i = end
    return "".join(chars)


def _line_comment_end(text, i):
    n = len(text)
    while True:
        j = text.find("\n", i)
        if j < 0:
            return n
        if j > 0 and text[j - 1] == "\\":  # a continued line comment
            i = j + 1
            continue
        return j


def _raw_string_end(text, quote):
    """Index after the raw string whose opening quote is at text[quote]: R"delim(...)delim"."""
    paren = text.find("(", quote + 1)
    if paren < 0:
        return len(text)
    closing = ")" + text[quote + 1:paren] + '"'
    found = text.find(closing, paren + 1)
    return len(text) if found < 0 else found + len(closing)


def _directive_end(text, i):
    """Index of the newline that ends the preprocessor line starting at text[i]."""
    n = len(text)
    while i < n:
        c = text[i]
        nxt = text[i + 1] if i + 1 < n else ""
        if c == "\\" and nxt == "\n":
            i += 2
        elif c == "\\" and text.startswith("\r\n", i + 1):
            i += 3
        elif c == "\n":
            return i
        elif c == "/" and nxt == "/":
            return _line_comment_end(text, i)
        elif c == "/" and nxt == "*":
            found = text.find("*/", i + 2)
            i = n if found < 0 else found + 2
        elif c in "\"'":
            i = _skip_quoted(text, i, c, True)
        else:
            i += 1
    return n


# --- tokens and scopes ------------------------------------------------------------------------

TOKEN = re.compile(r"[A-Za-z_]\w*|\.?\d[\w.']*|::|->|\.\.\.|==|!=|<=|>=|\S")
ACCESS = {"public", "private", "protected"}
CLASS_KEYS = {"class", "struct", "union"}
# a parenthesised group after one of these is not a parameter list
NOT_A_NAME = {"alignas", "decltype", "__attribute__", "__declspec", "noexcept", "sizeof",
              "alignof", "__typeof__", "typeof", "requires"}
Function = collections.namedtuple("Function", "name line end")


def tokenize(text):
    """[(text, line)] of the blanked text."""
    tokens = []
    line = 1
    pos = 0
    for m in TOKEN.finditer(text):
        line += text.count("\n", pos, m.start())
        pos = m.start()
        tokens.append((m.group(), line))
    return tokens


def _is_ident(tok):
    return tok[0].isalpha() or tok[0] == "_"


def _matching(tokens, i, opening, closing):
    """Index of the token that closes the group opened by tokens[i]."""
    depth = 0
    for k in range(i, len(tokens)):
        t = tokens[k][0]
        if t == opening:
            depth += 1
        elif t == closing:
            depth -= 1
            if depth == 0:
                return k
    return len(tokens) - 1


def _strip_prefix(stmt):
    """stmt without leading access specifiers, template headers and attributes."""
    k = 0
    while k < len(stmt):
        t = stmt[k][0]
        if t in ACCESS and k + 1 < len(stmt) and stmt[k + 1][0] == ":":
            k += 2
        elif t == "template" and k + 1 < len(stmt) and stmt[k + 1][0] == "<":
            k = _matching(stmt, k + 1, "<", ">") + 1
        elif t == "[" and k + 1 < len(stmt) and stmt[k + 1][0] == "[":
            k = _matching(stmt, k, "[", "]") + 1
        else:
            break
    return stmt[k:]


def _parameter_list(stmt):
    """(index of the `(` of the parameter list, index of the name's first token) or None."""
    paren = angle = bracket = 0
    k = 0
    while k < len(stmt):
        t = stmt[k][0]
        if t == "operator" and paren == bracket == 0:
            j = k + 1
            if j + 1 < len(stmt) and stmt[j][0] == "(" and stmt[j + 1][0] == ")":
                j += 2  # operator()
            while j < len(stmt) and stmt[j][0] != "(":
                j += 1
            return (j, k) if j < len(stmt) else None
        if t == "(" and paren == angle == bracket == 0:
            before = stmt[k - 1][0] if k > 0 else ""
            if before in NOT_A_NAME:
                k = _matching(stmt, k, "(", ")") + 1
                continue
            return (k, k - 1) if before and (_is_ident(before) or before == ">") else None
        if t == "=" and paren == angle == bracket == 0:
            return None  # an initializer: `auto f = [](int) {`, `T x = T(1) {`
        if t == "(":
            paren += 1
        elif t == ")":
            paren = max(0, paren - 1)
        elif t == "[":
            bracket += 1
        elif t == "]":
            bracket = max(0, bracket - 1)
        elif t == "<" and paren == bracket == 0:
            angle += 1
        elif t == ">" and paren == bracket == 0 and angle > 0:
            angle -= 1
        k += 1
    return None


def _before_template_args(stmt, close):
    """The index of the token before the `<` that matches the `>` at `close`."""
    depth = 0
    at = close
    while at > 0:
        depth += {">": 1, "<": -1}.get(stmt[at][0], 0)
        if depth == 0:
            break
        at -= 1
    return at - 1


def _qualified_name(stmt, paren, first):
    """The name as written before the parameter list, e.g. `GltfLoader::loadPrimitive`."""
    if stmt[first][0] == "operator":
        start = first
    else:
        start = first
        if stmt[start][0] == ">":  # f<int>( : a specialisation
            start = _before_template_args(stmt, start)
    if start > 0 and stmt[start - 1][0] == "~":
        start -= 1
    while start >= 2 and stmt[start - 1][0] == "::":
        prev = start - 2
        if stmt[prev][0] == ">":
            prev = _before_template_args(stmt, prev)
        if prev < 0 or not _is_ident(stmt[prev][0]):
            break
        start = prev
    name = ""
    for tok, _ in stmt[start:paren]:
        if name and _is_ident(tok) and (_is_ident(name[-1]) or name[-1].isdigit()):
            name += " "
        name += tok
    return name, stmt[first][1]


def _class_name(stmt):
    """The name of a class/struct/union head as written, e.g. `Renderer::Impl` (empty when
    anonymous)."""
    name = ""
    k = 1
    while k < len(stmt):
        t = stmt[k][0]
        if t in (":", "<", "{"):
            break
        if t == "(":
            k = _matching(stmt, k, "(", ")") + 1
            continue
        if t == "[":
            k = _matching(stmt, k, "[", "]") + 1
            continue
        if _is_ident(t) and t not in ("final", "alignas", "__attribute__", "__declspec"):
            name = name + "::" + t if stmt[k - 1][0] == "::" and name else t
        k += 1
    return name


def _init_list_pending(stmt, paren):
    """True when stmt, a function head, ends inside a constructor's member initializer list."""
    close = _matching(stmt, paren, "(", ")")
    depth = 0
    colon = False
    for t, _ in stmt[close + 1:]:
        depth += {"(": 1, ")": -1, "[": 1, "]": -1}.get(t, 0)
        colon = colon or (t == ":" and depth == 0)
    if not colon:
        return False
    last = stmt[-1][0]
    return _is_ident(last) or last == ">"


def scan(text):
    """[Function] of every function body defined at namespace, class or extern "C" scope."""
    tokens = tokenize(blank(text))
    found = []
    scopes = []  # (kind, name) of the enclosing namespaces, classes and extern blocks
    stmt = []
    paren = 0
    i = 0
    while i < len(tokens):
        tok, line = tokens[i]
        if tok == "{" and paren > 0:  # a brace inside parentheses: part of the statement
            i = _matching(tokens, i, "{", "}") + 1
            stmt.append(("{}", line))
            continue
        if tok == "{":
            i = _open_brace(tokens, i, stmt, scopes, found)
            if i < 0:  # an initializer brace of a constructor: the statement goes on
                i = -i
                stmt.append(("{}", line))
            else:
                stmt, paren = [], 0
            continue
        if tok == "}":
            if scopes:
                scopes.pop()
            stmt, paren = [], 0
        elif tok == ";" and paren == 0:
            stmt, paren = [], 0
        else:
            if tok == "(":
                paren += 1
            elif tok == ")":
                paren = max(0, paren - 1)
            stmt.append((tok, line))
        i += 1
    return found


def _open_brace(tokens, i, stmt, scopes, found):
    """Handles the `{` at tokens[i] at scope level; returns the index to go on from (negated
    when the brace belonged to a constructor's initializer list and the statement goes on)."""
    head = _strip_prefix(stmt)
    words = [t for t, _ in head]
    first = words[0] if words else ""
    if first == "inline" and len(words) > 1 and words[1] == "namespace":
        first = "namespace"
    if first == "namespace":
        scopes.append(("namespace", ""))
        return i + 1
    if words == ["extern"]:  # extern "C" { (the string is blanked)
        scopes.append(("extern", ""))
        return i + 1
    if first in ("typedef", "export") and len(words) > 1:
        head, words, first = head[1:], words[1:], words[1]
    if first in CLASS_KEYS and "=" not in words and _parameter_list(head) is None:
        scopes.append(("class", _class_name(head)))
        return i + 1
    close = _matching(tokens, i, "{", "}")
    if first != "enum":
        params = _parameter_list(head)
        if params is not None:
            paren, name_at = params
            if _init_list_pending(head, paren):
                return -(close + 1)
            while close + 2 < len(tokens) and tokens[close + 1][0] == "catch":
                # the handlers of a function-try-block: `Foo::Foo() try : m(1) {} catch (...) {}`
                after = _matching(tokens, close + 2, "(", ")") + 1
                if after >= len(tokens) or tokens[after][0] != "{":
                    break
                close = _matching(tokens, after, "{", "}")
            name, line = _qualified_name(head, paren, name_at)
            classes = [n for kind, n in scopes if kind == "class" and n]
            if classes and "::" not in name:
                name = "::".join(classes + [name])
            found.append(Function(name, line, tokens[close][1]))
    return close + 1


# --- the check --------------------------------------------------------------------------------

def functions(root):
    """[(lines, path, line, name)] of every C++ function under FOLDERS."""
    found = []
    for folder in FOLDERS:
        base = root / folder
        if not base.is_dir():
            continue
        for path in sorted(base.rglob("*")):
            if path.suffix not in SUFFIXES or not path.is_file():
                continue
            rel = path.relative_to(root).as_posix()
            text = path.read_text(encoding="utf-8", errors="replace")
            for f in scan(text):
                found.append((f.end - f.line + 1, rel, f.line, f.name))
    return found


def read_allowlist(path):
    """{(path, name): [(lines, list line)]}, or None when the file does not exist."""
    if not path.is_file():
        return None
    entries = collections.defaultdict(list)
    for number, row in enumerate(path.read_text().splitlines(), 1):
        row = row.strip()
        if not row or row.startswith("#"):
            continue
        cols = row.split()
        if len(cols) < 3 or not cols[-1].isdigit():
            sys.exit(f"{path}:{number}: expected `path name lines`, got `{row}`")
        entries[(cols[0], " ".join(cols[1:-1]))].append((int(cols[-1]), number))
    return entries


def write_allowlist(path, over):
    rows = sorted(over, key=lambda f: (f[1], f[2]))
    path.write_text(ALLOWLIST_HEADER + "".join(f"{p} {name} {lines}\n"
                                               for lines, p, _, name in rows))
    print(f"check-function-length: wrote {len(rows)} functions to {path}")


def ratchet(found, over, entries, limit, list_name):
    """(problems, notes): `file:line: message` for what the allowlist does not cover, and for
    listed functions that have shrunk (their listed length may come down)."""
    problems, notes = [], []
    over_by_key = collections.defaultdict(list)
    for f in over:
        over_by_key[(f[1], f[3])].append(f)
    all_by_key = collections.defaultdict(list)
    for f in found:
        all_by_key[(f[1], f[3])].append(f)
    for key in set(over_by_key) | set(entries):
        # overloads: the k-th longest definition is held to the k-th longest listed length
        defs = sorted(over_by_key.get(key, []), reverse=True)
        listed = sorted(entries.get(key, []), reverse=True)
        for (lines, p, line, name), (allowed, number) in zip(defs, listed):
            if lines > allowed:
                problems.append((p, line, f"{name} is {lines} lines, longer than its {allowed} "
                                          f"in {list_name}:{number}: split it rather than grow it"))
            elif lines < allowed:
                notes.append((p, line, f"note: {name} is {lines} lines, down from its {allowed}: "
                                       f"lower its length in {list_name}:{number}"))
        for lines, p, line, name in defs[len(listed):]:
            problems.append((p, line, f"{name} is {lines} lines (limit {limit})"))
        for allowed, number in listed[len(defs):]:
            p, name = key
            within = [f for f in all_by_key.get(key, []) if f[0] <= limit]
            if within:
                lines, _, line, _ = max(within)
                message = (f"{name} ({p}:{line}) is now {lines} lines, within the limit: "
                           "remove its line")
            else:
                message = f"{name} no longer exists in {p}: remove its line"
            problems.append((list_name, number, message))
    show = lambda rows: [f"{p}:{line}: {message}" for p, line, message in sorted(rows)]
    return show(problems), show(notes)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--limit", type=int, default=LIMIT)
    parser.add_argument("--root", type=pathlib.Path,
                        default=pathlib.Path(__file__).resolve().parent.parent)
    parser.add_argument("--list", type=int, default=0, help="print the N longest functions")
    parser.add_argument("--allowlist", type=pathlib.Path,
                        help=f"functions allowed over the limit (default ROOT/{ALLOWLIST}; "
                             "used with another --limit only when named)")
    parser.add_argument("--write-allowlist", action="store_true",
                        help="rewrite the allowlist from the current tree")
    args = parser.parse_args()
    list_path = args.allowlist or args.root / ALLOWLIST

    found = sorted(functions(args.root), key=lambda f: (-f[0], f[1], f[2], f[3]))
    if not found:
        print("check-function-length: no functions found (wrong --root?)")
        return 1
    for lines, path, line, name in found[:args.list]:
        print(f"{lines:5d}  {path}:{line} {name}")
    over = [f for f in found if f[0] > args.limit]
    if args.write_allowlist:
        if args.limit != LIMIT and args.allowlist is None:
            sys.exit(f"check-function-length: {ALLOWLIST} holds for --limit {LIMIT}; "
                     "name another file with --allowlist")
        write_allowlist(list_path, over)
        return 0

    use_list = args.allowlist is not None or args.limit == LIMIT
    entries = read_allowlist(list_path) if use_list else None
    if entries is None:
        entries = {}
    try:
        list_name = list_path.resolve().relative_to(args.root.resolve()).as_posix()
    except ValueError:
        list_name = str(list_path)
    problems, notes = ratchet(found, over, entries, args.limit, list_name)
    for row in problems + notes:
        print(row)
    if problems:
        print(f"check-function-length: {len(problems)} problems, {len(over)} of {len(found)} "
              f"functions over {args.limit} lines: split new ones into steps with one job each")
        return 1
    lines, path, line, name = found[0]
    print(f"check-function-length: {len(found)} functions, {len(over)} over {args.limit} lines, "
          f"all listed in {list_name} and none grown (longest: {name}, {lines}, {path}:{line})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
