"""Griffe extension for the API reference: the docstrings' reST markup as Markdown.

shellbuckle's docstrings are written in plain reST (Sphinx roles, ``::`` literal blocks,
underlined section titles) and read well as text; mkdocstrings renders Markdown. Before
rendering, this extension rewrites, in every docstring of the package:

- roles such as :class:`~shellbuckle.run.Run`, :func:`deflate` or :mod:`.descriptors` into
  optional cross-references (a link where the target is documented in the reference, plain code
  where it is not, never a warning);
- a paragraph ending in ``::`` followed by an indented block into that paragraph and a fenced
  code block;
- underlined titles other than the NumPy-style sections (``Parameters``, ``Returns``, ...)
  into bold lines, so that they do not become headings of the page.

Loaded by ``mkdocs.yml`` (``extensions: - docs/_ext/rst_markup.py``); it changes nothing in the
package itself.
"""

from __future__ import annotations

import html
import re

import griffe

ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|exc|obj|const):`(~?)([^`]+)`")
UNDERLINE = re.compile(r"^\s*(-{3,}|={3,}|~{3,})\s*$")
NUMPY_SECTIONS = {"parameters", "other parameters", "returns", "yields", "receives", "raises",
                  "warns", "attributes", "methods", "examples", "see also", "notes",
                  "references", "warnings", "functions", "classes", "modules"}


def _module(obj: griffe.Object) -> griffe.Object:
    while not obj.is_module:
        obj = obj.parent
    return obj


def _target(obj: griffe.Object, name: str, collection) -> str:
    """The documented path that ``name``, written in ``obj``'s docstring, refers to."""
    name = name.strip().rstrip("()")
    if name.startswith("."):
        module = _module(obj)
        base = module if module.is_package else module.parent
        dots = len(name) - len(name.lstrip("."))
        for _ in range(dots - 1):
            base = base.parent if base.parent is not None else base
        path = f"{base.path}.{name.lstrip('.')}"
    else:
        head, _, rest = name.partition(".")
        try:
            path = obj.resolve(head) + (f".{rest}" if rest else "")
        except griffe.NameResolutionError:
            path = name
    try:
        found = collection[path]
        if found.is_alias:
            path = found.final_target.path
    except (KeyError, griffe.AliasResolutionError, griffe.CyclicAliasError):
        pass
    return path


def _roles(lines: list[str], obj: griffe.Object, collection) -> list[str]:
    def replace(match: re.Match) -> str:
        short, name = match.group(1), match.group(2)
        shown = name.strip().lstrip(".")
        if short:
            shown = shown.rsplit(".", 1)[-1]
        target = _target(obj, name, collection)
        return (f'<autoref identifier="{html.escape(target)}" optional>'
                f"<code>{html.escape(shown)}</code></autoref>")

    out, fenced = [], False
    for line in lines:
        if line.strip().startswith("```"):
            fenced = not fenced
        out.append(line if fenced else ROLE.sub(replace, line))
    return out


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip(" "))


def _literal_blocks(lines: list[str]) -> list[str]:
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line.rstrip().endswith("::"):
            out.append(line)
            i += 1
            continue
        j = i + 1
        while j < len(lines) and not lines[j].strip():
            j += 1
        base = _indent(line)
        if j >= len(lines) or _indent(lines[j]) <= base:
            out.append(line)
            i += 1
            continue
        stripped = line.rstrip()[:-2].rstrip()
        if stripped:
            ends_word = line.rstrip()[-3:-2] not in (" ", "")
            out.append(stripped + (":" if ends_word else ""))
        block_indent = _indent(lines[j])
        k = j
        block: list[str] = []
        while k < len(lines) and (not lines[k].strip() or _indent(lines[k]) >= block_indent):
            block.append(lines[k])
            k += 1
        while block and not block[-1].strip():
            block.pop()
        pad = " " * base
        out.append("")
        out.append(pad + "```text")
        out.extend(pad + b[block_indent:] if b.strip() else "" for b in block)
        out.append(pad + "```")
        out.append("")
        i = k
    return out


def _titles(lines: list[str]) -> list[str]:
    out: list[str] = []
    for line in lines:
        if (UNDERLINE.match(line) and out and out[-1].strip()
                and len(line.strip()) == len(out[-1].strip())
                and out[-1].strip().lower() not in NUMPY_SECTIONS):
            title = out.pop()
            out.append(" " * _indent(title) + f"**{title.strip()}**")
            continue
        out.append(line)
    return out


class RstMarkup(griffe.Extension):
    """Rewrite the reST markup of every docstring of a loaded package as Markdown."""

    def on_package(self, *, pkg: griffe.Module, loader: griffe.GriffeLoader, **kwargs) -> None:
        collection = loader.modules_collection
        seen: set[int] = set()

        def visit(obj: griffe.Object) -> None:
            if id(obj) in seen:
                return
            seen.add(id(obj))
            if obj.docstring is not None:
                lines = _titles(_literal_blocks(obj.docstring.value.split("\n")))
                obj.docstring.value = "\n".join(_roles(lines, obj, collection))
            for member in obj.members.values():
                if not member.is_alias:
                    visit(member)

        visit(pkg)
