#!/usr/bin/env python3
"""check_layout.py ROOT: checks the layering that docs/ARCHITECTURE.md draws.

Rules, each a failure line when broken:
  1. Includes point one way. A quoted #include in
       base/     may name base/ only;
       formats/  may name base/ and formats/;
       kernels/  may name kernels/ only, always as "kernels/NAME" (the same
                 text resolves on the host and from the embedded kernels);
       baker/    may name base/, formats/, kernels/ and baker/.
     A header is found beside the including file, then under ROOT/base,
     ROOT/formats, ROOT/baker, then ROOT (the build's include path).
  2. Kernel headers have names that exist once: no kernels/X.h beside a
     base/X.h, formats/X.h or baker/X.h.
  3. The photon march knows nothing of the adaptive pipeline: neither
     kernels/photon_march.h nor baker/march.[ch] reaches (through includes)
     a file whose name starts with "adaptive".
  4. Sizes: no source file in base/, formats/, kernels/, baker/ over
     MAX_FILE_LINES lines, no function over MAX_FUNCTION_LINES
     (functions found as the shared tools/fnlen.py finds them).
Exit 0 when every rule holds, 1 otherwise (one line per problem)."""
import os
import re
import sys

MAX_FILE_LINES = 700
MAX_FUNCTION_LINES = 100
LAYERS = {
    "base": {"base"},
    "formats": {"base", "formats"},
    "kernels": {"kernels"},
    "baker": {"base", "formats", "kernels", "baker"},
}
SOURCE_EXT = (".c", ".h", ".cpp", ".cl")
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')


def sources(root):
    for layer in LAYERS:
        d = os.path.join(root, layer)
        if not os.path.isdir(d):
            continue
        for name in sorted(os.listdir(d)):
            if name.endswith(SOURCE_EXT):
                yield layer, os.path.join(d, name)


def includes(path):
    with open(path, errors="replace") as f:
        for no, line in enumerate(f, 1):
            m = INCLUDE.match(line)
            if m:
                yield no, m.group(1)


def resolve(root, path, name):
    """The file a quoted include names, as the compiler finds it, or None."""
    here = os.path.join(os.path.dirname(path), name)
    if os.path.exists(here):
        return os.path.normpath(here)
    for d in ("base", "formats", "baker", ""):
        p = os.path.join(root, d, name)
        if os.path.exists(p):
            return os.path.normpath(p)
    return None


def layer_of(root, path):
    rel = os.path.relpath(path, root)
    return rel.split(os.sep)[0]


def check_includes(root, problems):
    for layer, path in sources(root):
        rel = os.path.relpath(path, root)
        for no, name in includes(path):
            target = resolve(root, path, name)
            if target is None:
                if layer == "kernels" or name.startswith("kernels/"):
                    problems.append(f"{rel}:{no}: #include \"{name}\": no such file")
                continue  # generated files (kernels_embedded.c's clhost.h) and the like
            to = layer_of(root, target)
            if to not in LAYERS[layer]:
                problems.append(f"{rel}:{no}: #include \"{name}\": {layer}/ may not include {to}/")
            if to == "kernels" and not name.startswith("kernels/"):
                problems.append(f"{rel}:{no}: #include \"{name}\": name kernel headers "
                                f"with their directory, \"kernels/{os.path.basename(name)}\"")


def check_unique_names(root, problems):
    kdir = os.path.join(root, "kernels")
    if not os.path.isdir(kdir):
        return
    for name in sorted(os.listdir(kdir)):
        if not name.endswith(".h"):
            continue
        for other in ("base", "formats", "baker"):
            if os.path.exists(os.path.join(root, other, name)):
                problems.append(f"kernels/{name}: {other}/{name} has the same name")


def reach(root, start):
    seen, todo = set(), [start]
    while todo:
        p = todo.pop()
        if p in seen or not os.path.exists(p):
            continue
        seen.add(p)
        for _, name in includes(p):
            t = resolve(root, p, name)
            if t:
                todo.append(t)
    return seen


def check_march_independent(root, problems):
    for rel in ("kernels/photon_march.h", "baker/march.h", "baker/march.c"):
        start = os.path.join(root, rel)
        if not os.path.exists(start):
            problems.append(f"{rel}: missing (the march's files moved? update this check)")
            continue
        for p in sorted(reach(root, start)):
            if os.path.basename(p).startswith("adaptive"):
                problems.append(f"{rel}: reaches {os.path.relpath(p, root)} through its includes")


def functions(lines):
    """(length, first line, name) of each function, as tools/fnlen.py counts."""
    i, n = 0, len(lines)
    while i < n:
        l = lines[i]
        if (re.match(r"^[A-Za-z_].*\(", l) and not l.startswith("#") and not l.rstrip().endswith(";")
                and not re.match(r"^(typedef|struct|enum|static const|extern)\b.*[;=]", l)):
            j = i
            while j < n and "{" not in lines[j] and not lines[j].rstrip().endswith(";"):
                j += 1
            if j < n and "{" in lines[j] and not lines[j].rstrip().endswith(";"):
                depth, k = 0, j
                while k < n:
                    depth += lines[k].count("{") - lines[k].count("}")
                    if depth <= 0:
                        break
                    k += 1
                m = re.search(r"([A-Za-z_][A-Za-z0-9_]*)\s*\(", l)
                yield k - i + 1, i + 1, m.group(1) if m else l
                i = k + 1
                continue
        i += 1


def check_sizes(root, problems):
    for _, path in sources(root):
        rel = os.path.relpath(path, root)
        with open(path, errors="replace") as f:
            lines = f.read().split("\n")
        if len(lines) > MAX_FILE_LINES:
            problems.append(f"{rel}: {len(lines)} lines (at most {MAX_FILE_LINES}): split it at a seam")
        for length, first, name in functions(lines):
            if length > MAX_FUNCTION_LINES:
                problems.append(f"{rel}:{first}: {name} is {length} lines "
                                f"(at most {MAX_FUNCTION_LINES}): split it at a seam")


def main():
    root = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else ".")
    problems = []
    check_includes(root, problems)
    check_unique_names(root, problems)
    check_march_independent(root, problems)
    check_sizes(root, problems)
    for p in problems:
        print("FAIL " + p)
    print(f"check_layout: {len(problems)} problem(s) in {sum(1 for _ in sources(root))} files")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
