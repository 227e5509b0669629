"""Read and write Surface Evolver datafiles (``.fe``) and dump files (``.dmp``).

What is read (Surface Evolver 2.70 manual, "Datafile format" and "General syntax"):

- the top section: ``PARAMETER name = value``, ``define vertex|edge|facet|body attribute name
  real|integer[n]``, ``QUANTITY name ENERGY|INFO_ONLY|FIXED = v|CONSERVED [MODULUS m] METHOD
  name [GLOBAL] | GLOBAL_METHOD name``, ``METHOD_INSTANCE name METHOD m [MODULUS m] [GLOBAL]``,
  ``#define`` macros and ``#include`` files; everything else in the top section (constraints,
  view matrix, toggles, ...) is recorded in :attr:`EvolverFile.skipped`;
- ``vertices`` (``id x y z [fixed] [constraint ...] [attribute values] [quantity names]``),
  ``edges`` (``id tail head ...``), ``faces``/``facets`` (``id e1 e2 e3 ...`` with signed edge
  numbers: a negative number runs the edge backwards) and ``bodies`` (``id f1 f2 ... [volume
  v]`` with signed facet numbers: negative means the facet normal points into the body);
- comments (``//`` and ``/* */``), ``\\`` line splicing, case-insensitive keywords, commas,
  colons and semicolons as whitespace, constant expressions (numbers, parameters, ``pi``,
  ``+ - * / ^``, parentheses, the usual math functions; ``3 -5`` is two numbers, ``3 - 5``
  one expression, as in Evolver).

The ``read`` section at the end of a datafile holds commands Evolver executes on loading; it is
never executed here: the reader stops at ``read``, logs that it skipped it and records it.

Orientation. Evolver's facet vertex order starts at the tail of the first edge listed for the
facet (this is the ``v0`` of ``form_factors``). The mesh faces keep that order, reversed to
``(v0, v2, v1)`` where needed so that all normals point out of the body (``facet_sign = -1``);
``form_factors`` are stored in the mesh face order (``(s22, s12, s11)`` for reversed facets).

Only what a closed triangulated shell needs is supported: soapfilm, linear model, 3D, one body
(or none), triangular facets. Anything else raises a ``ValueError`` naming the file and line.
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .mesh import Mesh

log = logging.getLogger(__name__)

__all__ = ["EvolverFile", "EvolverQuantity", "read_evolver", "write_evolver"]


# ----------------------------------------------------------------------------------------------
# Data
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EvolverQuantity:
    """One method instance of a named quantity.

    ``modulus`` is the product of the quantity's and the method instance's moduli (Evolver
    multiplies both). ``vertices``/``facets`` are mesh indices of the elements a non-global
    instance was applied to in the file (``None`` for a global instance).
    """

    name: str
    kind: str  # "energy", "info_only", "fixed", "conserved"
    method: str  # lower case, e.g. "linear_elastic", "star_perp_sq_mean_curvature"
    modulus: float = 1.0
    is_global: bool = True
    instance: str | None = None
    vertices: np.ndarray | None = field(default=None, repr=False, compare=False)
    facets: np.ndarray | None = field(default=None, repr=False, compare=False)
    line: int = 0


@dataclass(frozen=True, eq=False)
class EvolverFile:
    """The contents of a Surface Evolver datafile or dump that define a closed shell.

    Attributes
    ----------
    path : str or None
    mesh : Mesh
        Vertex positions and outward-oriented faces. Mesh vertex ``k`` is Evolver vertex
        ``vertex_ids[k]``; mesh face ``f`` is Evolver facet ``facet_ids[f]``.
    vertex_ids, facet_ids : (V,), (F,) int
    facet_sign : (F,) int
        +1 where the mesh face has the Evolver facet's orientation, -1 where it is reversed.
    fixed : (V,) bool
        Vertices marked ``fixed``.
    facet_tension : (F,) float
        Facet surface tension (``tension``/``density``; Evolver's default is 1).
    poisson_ratio : (F,) float or None
        The ``poisson_ratio`` facet attribute, if defined (0 where not given).
    form_factors : (F, 3) float or None
        The ``form_factors`` facet attribute ``(s11, s12, s22)`` (rest-shape Gram matrix,
        ``s11 = |x1 - x0|^2``, ``s12 = (x1 - x0).(x2 - x0)``, ``s22 = |x2 - x0|^2``), in the mesh
        face vertex order; zeros where not given.
    h_zero : float, (V,) float or None
        Evolver's ``h_zero``: the vertex attribute if defined (it takes precedence in Evolver),
        else the global parameter, else ``None`` (Evolver then uses 0).
    volume : float or None
        The body's target volume (``volume``), if any.
    quantities : tuple of EvolverQuantity
    parameters : dict
        ``PARAMETER`` values by lower-case name.
    skipped : tuple of str
        What the file contains that is not represented here, one note per item with its line.
    """

    path: str | None
    mesh: Mesh
    vertex_ids: np.ndarray
    facet_ids: np.ndarray
    facet_sign: np.ndarray
    fixed: np.ndarray
    facet_tension: np.ndarray
    poisson_ratio: np.ndarray | None
    form_factors: np.ndarray | None
    h_zero: float | np.ndarray | None
    volume: float | None
    quantities: tuple
    parameters: dict
    skipped: tuple

    def energy_quantities(self, method: str) -> list:
        """The ``energy`` method instances using ``method`` (lower case)."""
        return [q for q in self.quantities if q.kind == "energy" and q.method == method.lower()]


# ----------------------------------------------------------------------------------------------
# Lexical layer: comments, splicing, tokens, constant expressions
# ----------------------------------------------------------------------------------------------
class _Tok:
    __slots__ = ("kind", "value", "signed")

    def __init__(self, kind, value, signed=False):
        self.kind, self.value, self.signed = kind, value, signed

    def __repr__(self):
        return f"{self.kind}:{self.value!r}"


_WHITESPACE = " \t,;:\x1a\r"
_OPERATORS = ("**", "==", "!=", "<=", ">=", "&&", "||", ":=", "+", "-", "*", "/", "^", "(", ")",
              "{", "}", "[", "]", "=", "%", "<", ">", "!", "?", "@", "'", "|", "&", "~")

_FUNCTIONS = {
    "sqrt": math.sqrt, "sin": math.sin, "cos": math.cos, "tan": math.tan, "asin": math.asin,
    "acos": math.acos, "atan": math.atan, "exp": math.exp, "log": math.log, "abs": abs,
    "sinh": math.sinh, "cosh": math.cosh, "tanh": math.tanh, "asinh": math.asinh,
    "acosh": math.acosh, "atanh": math.atanh, "ceil": math.ceil, "floor": math.floor,
    "sqr": lambda v: v * v,
}
_FUNCTIONS2 = {"atan2": math.atan2, "pow": math.pow, "maximum": max, "minimum": min,
               "max": max, "min": min}
_COLORS = {"clear": -1, "transparent": -1, "black": 0, "blue": 1, "green": 2, "cyan": 3, "red": 4,
           "magenta": 5, "brown": 6, "lightgray": 7, "lightgrey": 7, "darkgray": 8, "darkgrey": 8,
           "lightblue": 9, "lightgreen": 10, "lightcyan": 11, "lightred": 12, "lightmagenta": 13,
           "yellow": 14, "white": 15}


def _parse_number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        if text[:2].lower() == "0x":
            return float(int(text, 16))
        return float(text.replace("d", "e").replace("D", "e"))


_TOKEN = re.compile(
    r"(?P<ws>[ \t,;:\x1a\r]+)"
    r'|(?P<str>"[^"]*")'
    r"|(?P<num>0[xX][0-9a-fA-F]+|(?:\d+\.?\d*|\.\d+)(?:[eEdD][+-]?\d+)?)"
    r"|(?P<ident>[A-Za-z_][A-Za-z0-9_.]*)"
    r"|(?P<op>" + "|".join(re.escape(op) for op in _OPERATORS) + ")")
_PLAIN_NUMBERS = re.compile(r"[-+0-9.eE \t]+")


def _tokenize(text: str, where: str, macros: dict, lists: bool = False) -> list:
    """Tokens of one logical line.

    With ``lists`` (element lines, where Evolver's lexer sets ``uminus_flag``), a sign preceded
    by whitespace and outside parentheses starts a new expression, as in Evolver: ``-5`` or
    ``+5`` becomes a signed number and ``-`` followed by a non-blank a leading (unary) minus, so
    ``0 -1 -sqrt(2)`` is three values and ``0 - 1`` one. Elsewhere signs are ordinary operators.
    """
    if lists and _PLAIN_NUMBERS.fullmatch(text):  # fast path: a line of plain numbers
        try:
            return [_Tok("num", float(w), signed=w[0] in "+-") for w in text.split()]
        except ValueError:
            pass  # e.g. a lone '-': use the general scanner
    toks = []
    i, n = 0, len(text)
    after_space = True
    parens = 0
    while i < n:
        m = _TOKEN.match(text, i)
        if m is None:
            if text[i] == '"':
                raise ValueError(f"{where}: unterminated string")
            raise ValueError(f"{where}: unexpected character {text[i]!r}")
        kind, word = m.lastgroup, m.group()
        i = m.end()
        if kind == "ws":
            after_space = True
            continue
        if kind == "str":
            toks.append(_Tok("str", word[1:-1]))
        elif kind == "num":
            if i < n and text[i] in "bB" and re.fullmatch(r"[01]+", word):
                toks.append(_Tok("num", float(int(word, 2))))  # binary 1011b
                i += 1
            else:
                toks.append(_Tok("num", _parse_number(word)))
        elif kind == "ident":
            if word in macros:
                toks.extend(_tokenize(macros[word], where,
                                      {k: v for k, v in macros.items() if k != word}, lists))
            else:
                toks.append(_Tok("ident", word))
        else:
            if lists and word in "+-" and after_space and parens == 0 and i < n:
                nxt = _TOKEN.match(text, i)
                if nxt is not None and nxt.lastgroup == "num":
                    value = _parse_number(nxt.group())
                    toks.append(_Tok("num", -value if word == "-" else value, signed=True))
                    i = nxt.end()
                    after_space = False
                    continue
                if word == "-" and text[i] not in _WHITESPACE:
                    toks.append(_Tok("op", "-", signed=True))  # leading minus of a new expression
                    after_space = False
                    continue
            toks.append(_Tok("op", word))
            parens += (word == "(") - (word == ")")
        after_space = False
    return toks


class _Expr:
    """Recursive-descent evaluator of Evolver constant expressions on a token list."""

    def __init__(self, toks, pos, params, where):
        self.toks, self.pos, self.params, self.where = toks, pos, params, where

    def peek(self):
        return self.toks[self.pos] if self.pos < len(self.toks) else None

    def is_op(self, *ops):
        t = self.peek()
        return t is not None and t.kind == "op" and t.value in ops

    def fail(self, msg):
        raise ValueError(f"{self.where}: {msg}")

    def expr(self):
        value = self.term()
        while self.is_op("+", "-") and not self.peek().signed:
            op = self.toks[self.pos].value
            self.pos += 1
            rhs = self.term()
            value = value + rhs if op == "+" else value - rhs
        return value

    def term(self):
        value = self.unary()
        while self.is_op("*", "/", "%"):
            op = self.toks[self.pos].value
            self.pos += 1
            rhs = self.unary()
            if op == "*":
                value *= rhs
            elif rhs == 0:
                self.fail("division by zero in a constant expression")
            elif op == "/":
                value /= rhs
            else:
                value = value - math.floor(value / rhs) * rhs
        return value

    def unary(self):
        if self.is_op("-"):
            self.pos += 1
            return -self.unary()
        if self.is_op("+"):
            self.pos += 1
            return self.unary()
        return self.power()

    def power(self):
        base = self.primary()
        if self.is_op("^", "**"):
            self.pos += 1
            return base ** self.unary()
        return base

    def primary(self):
        t = self.peek()
        if t is None:
            self.fail("expected a number or an expression, found the end of the line")
        if t.kind == "num":
            self.pos += 1
            return t.value
        if t.kind == "op" and t.value == "(":
            self.pos += 1
            value = self.expr()
            self.expect(")")
            return value
        if t.kind == "ident":
            name = t.value.lower()
            self.pos += 1
            if name in _FUNCTIONS or name in _FUNCTIONS2:
                self.expect("(")
                args = [self.expr()]
                while not self.is_op(")"):
                    if self.peek() is None:
                        self.fail(f"unclosed call of {name}")
                    args.append(self.expr())
                self.expect(")")
                fn = _FUNCTIONS.get(name) or _FUNCTIONS2[name]
                try:
                    return float(fn(*args))
                except (TypeError, ValueError, OverflowError) as exc:
                    self.fail(f"cannot evaluate {name}{tuple(args)}: {exc}")
            if name == "pi":
                return math.pi
            if name in self.params:
                return self.params[name]
            self.fail(f"unknown name {t.value!r} in an expression (not a parameter defined above)")
        self.fail(f"expected a number or an expression, found {t.value!r}")

    def expect(self, op):
        if not self.is_op(op):
            t = self.peek()
            self.fail(f"expected {op!r}, found {t.value if t else 'the end of the line'!r}")
        self.pos += 1


def _eval(toks, pos, params, where):
    """Evaluate the longest constant expression starting at ``pos``; return (value, new pos).

    A signed number (``-5`` right after whitespace) is a ``num`` token, not an operator, so it
    ends the expression before it: ``0 -1 2`` is three expressions, ``0 - 1`` one.
    """
    ev = _Expr(toks, pos, params, where)
    return ev.expr(), ev.pos


def _strip_line(raw: str, in_block: bool):
    """Remove ``//`` and ``/* */`` comments (outside double quotes) from one physical line.

    Returns the text and whether a block comment is still open at the end of the line."""
    if not in_block and "/" not in raw:
        return raw, False
    out = []
    i, n = 0, len(raw)
    in_str = False
    while i < n:
        if in_block:
            j = raw.find("*/", i)
            if j < 0:
                break
            in_block = False
            i = j + 2
            out.append(" ")
            continue
        ch = raw[i]
        if in_str:
            out.append(ch)
            in_str = not (ch == '"' and raw[i - 1] != "\\")
            i += 1
        elif ch == '"':
            in_str = True
            out.append(ch)
            i += 1
        elif raw.startswith("//", i):
            break
        elif raw.startswith("/*", i):
            in_block = True
            i += 2
        else:
            out.append(ch)
            i += 1
    return "".join(out), in_block


def _strip_comments(lines, path_label):
    """Yield ``(line_number, text)`` with comments removed and ``\\``-spliced lines joined.

    The scan is lazy so that the caller can stop at the ``read`` keyword before the command
    text after it is looked at.
    """
    in_block = False
    pending, pending_no = "", None
    for no, raw in enumerate(lines, start=1):
        text, in_block = _strip_line(raw, in_block)
        text = text.rstrip()
        if pending_no is None:
            pending_no = no
        if text.endswith("\\"):
            pending += text[:-1] + " "
            continue
        yield pending_no, pending + text
        pending, pending_no = "", None
    if pending_no is not None:
        yield pending_no, pending


# ----------------------------------------------------------------------------------------------
# Parser
# ----------------------------------------------------------------------------------------------
_SECTIONS = {"vertices": "vertices", "edges": "edges", "faces": "faces", "facets": "faces",
             "bodies": "bodies", "read": "read"}
_UNSUPPORTED_MODEL = {
    "string": "the string model (curves)", "quadratic": "the quadratic model",
    "lagrange": "the Lagrange model", "lagrange_order": "the Lagrange model",
    "torus": "the torus model", "torus_filled": "the torus model",
    "simplex_representation": "the simplex model", "symmetry_group": "symmetry groups",
    "metric": "a Riemannian metric", "conformal_metric": "a conformal metric",
    "klein_metric": "the Klein metric",
}
_SKIPPED_ENERGIES = ("squared_curvature", "square_curvature", "sqgauss", "square_gaussian_curvature",
                     "squared_gaussian_curvature", "mean_curvature_integral", "gauss_curvature")
_QUANTITY_KINDS = {"energy": "energy", "info_only": "info_only", "fixed": "fixed",
                   "conserved": "conserved"}
_FACET_METHODS = {"linear_elastic"}
_VERTEX_METHODS = {"star_perp_sq_mean_curvature"}


@dataclass
class _Attr:
    etype: str
    size: int  # number of reals (1 for a scalar)


@dataclass
class _Instance:
    name: str
    method: str
    modulus: float
    is_global: bool
    line: int
    quantity: str | None = None


@dataclass
class _Quantity:
    name: str
    kind: str
    modulus: float
    line: int
    instances: list = field(default_factory=list)


class _Parser:
    def __init__(self, text: str, label: str, base_dir: Path):
        self.label = label
        self.base_dir = base_dir
        self.lines = text.splitlines()
        self.params: dict = {}
        self.macros: dict = {}
        self.attrs: dict = {}  # (etype, name) -> _Attr
        self.instances: dict = {}  # lower name -> _Instance
        self.quantities: dict = {}  # lower name -> _Quantity
        self.constraint_names: set = set()
        self.skipped: list = []
        self.vertex_rows, self.edge_rows, self.face_rows, self.body_rows = [], [], [], []

    def where(self, no):
        return f"{self.label}, line {no}"

    def skip(self, no, what):
        self.skipped.append(f"line {no}: {what}")

    # -- driver ---------------------------------------------------------------------------
    def run(self):
        section = "top"
        brace_depth = 0
        for no, text in self._logical_lines(self.lines, self.label, depth=0):
            stripped = text.strip()
            if not stripped:
                continue
            where = self.where(no)
            if brace_depth > 0:  # inside a procedure/function body in the top section
                brace_depth += stripped.count("{") - stripped.count("}")
                continue
            words = re.split(r"[ \t,;:]+", stripped, maxsplit=1)  # ',;:' are whitespace too
            words = [w for w in words if w]
            first = words[0].lower()
            if first in _SECTIONS:
                new = _SECTIONS[first]
                if new == "read":
                    rest = len(self.lines) - no
                    self.skip(no, f"'read' section of commands ({rest} lines after it) was not executed")
                    log.info("%s: skipped the 'read' section (commands are never executed)", where)
                    break
                if len(words) > 1:
                    raise ValueError(f"{where}: unexpected text after {words[0]!r}: {words[1]!r}")
                section = new
                continue
            if section == "top":
                opened = stripped.count("{") - stripped.count("}")
                if opened > 0 or first in ("procedure", "function"):
                    brace_depth = max(opened, 0)  # a command body: skipped, never parsed
                    self.skip(no, f"definition {stripped[:60]!r} (not executed)")
                    continue
                self._top(_tokenize(text, where, self.macros), no, stripped)
            else:
                getattr(self, "_" + section)(_tokenize(text, where, self.macros, lists=True), no)
        if brace_depth > 0:
            raise ValueError(f"{self.label}: unbalanced '{{' in the top section")

    def _logical_lines(self, lines, label, depth):
        for no, text in _strip_comments(lines, label):
            s = text.strip()
            if s.lower().startswith("#define"):
                parts = s.split(None, 2)
                if len(parts) < 2:
                    raise ValueError(f"{label}, line {no}: #define needs a name")
                self.macros[parts[1]] = parts[2] if len(parts) > 2 else ""
                continue
            if s.lower().startswith("#include"):
                m = re.match(r'#include\s+"([^"]+)"', s, re.IGNORECASE)
                if m is None:
                    raise ValueError(f"{label}, line {no}: #include needs a double-quoted file name")
                if depth >= 10:
                    raise ValueError(f"{label}, line {no}: #include nested more than 10 deep")
                inc = (self.base_dir / m.group(1))
                if not inc.is_file():
                    raise ValueError(f"{label}, line {no}: included file {m.group(1)!r} not found "
                                     f"(looked in {self.base_dir})")
                yield from self._logical_lines(inc.read_text(errors="replace").splitlines(),
                                               f"{label} -> {inc.name}", depth + 1)
                continue
            if s.startswith("#"):
                raise ValueError(f"{label}, line {no}: unsupported preprocessor line {s[:40]!r}")
            yield no, text

    # -- top section ------------------------------------------------------------------------
    def _top(self, toks, no, text):
        where = self.where(no)
        if not toks:
            return
        t0 = toks[0]
        if t0.kind != "ident":
            return  # values continuing the previous keyword (e.g. the rows of VIEW_MATRIX)
        key = t0.value.lower()
        if key in ("parameter", "optimizing_parameter", "optimising_parameter"):
            self._parameter(toks, no)
        elif key == "define":
            self._define(toks, no)
        elif key == "quantity":
            self._quantity(toks, no)
        elif key == "method_instance":
            self._method_instance(toks, no)
        elif key in _UNSUPPORTED_MODEL:
            raise ValueError(f"{where}: {_UNSUPPORTED_MODEL[key]} is not supported; "
                             "only a linear-model soapfilm surface in 3D can be read")
        elif key == "space_dimension":
            if len(toks) < 2 or toks[1].kind != "num" or toks[1].value != 3:
                raise ValueError(f"{where}: only space_dimension 3 is supported")
        elif key == "surface_dimension":
            if len(toks) < 2 or toks[1].kind != "num" or toks[1].value != 2:
                raise ValueError(f"{where}: only surface_dimension 2 (soapfilm) is supported")
        elif key in ("soapfilm", "linear", "keep_originals", "evolver_version") or key.endswith("_predicted"):
            return
        elif key in ("constraint", "boundary"):
            if len(toks) > 1 and toks[1].kind == "ident":
                self.constraint_names.add(toks[1].value.lower())
            self.skip(no, f"{key} definition {text[:60]!r}")
        elif key in _SKIPPED_ENERGIES:
            self.skip(no, f"energy {key!r} is not computed here")
            log.warning("%s: energy %r is not computed by shellbuckle", where, key)
        else:
            self.skip(no, f"{text[:60]!r}")

    def _parameter(self, toks, no):
        where = self.where(no)
        if len(toks) < 2 or toks[1].kind != "ident":
            raise ValueError(f"{where}: PARAMETER needs a name")
        name = toks[1].value.lower()
        if len(toks) > 2 and toks[2].kind == "op" and toks[2].value == "[":
            self.skip(no, f"array parameter {toks[1].value!r}")
            return
        value, pos = 0.0, 2
        if len(toks) > 2 and toks[2].kind == "op" and toks[2].value == "=":
            value, pos = _eval(toks, 3, self.params, where)
        elif len(toks) > 2 and toks[2].kind == "ident" and toks[2].value.lower() == "parameter_file":
            raise ValueError(f"{where}: parameter_file is not supported")
        self.params[name] = float(value)

    def _define(self, toks, no):
        where = self.where(no)
        words = [t.value.lower() if t.kind == "ident" else t.value for t in toks]
        if len(words) >= 5 and words[2] == "attribute":
            etype = {"vertex": "vertex", "edge": "edge", "facet": "facet", "face": "facet",
                     "body": "body"}.get(words[1])
            if etype is None:
                raise ValueError(f"{where}: unknown element type {toks[1].value!r} in define")
            name = words[3]
            size, pos = 1, 5
            while pos < len(toks) and toks[pos].kind == "op" and toks[pos].value == "[":
                dim, pos = _eval(toks, pos + 1, self.params, where)
                if pos >= len(toks) or toks[pos].value != "]":
                    raise ValueError(f"{where}: expected ']' in the attribute dimension")
                size *= int(dim)
                pos += 1
            self.attrs[(etype, name)] = _Attr(etype, size)
            if pos < len(toks) and toks[pos].kind == "ident" and toks[pos].value.lower() == "function":
                self.skip(no, f"attribute function of {name!r} (not executed)")
            return
        self.skip(no, f"define {' '.join(str(w) for w in words[1:4])}")

    def _method_list(self, toks, pos, no, owner_modulus, quantity_name):
        """Parse ``METHOD name [GLOBAL] | GLOBAL_METHOD name`` items; return instances."""
        where = self.where(no)
        found = []
        while pos < len(toks):
            t = toks[pos]
            word = t.value.lower() if t.kind == "ident" else None
            if word in ("method", "global_method"):
                if pos + 1 >= len(toks) or toks[pos + 1].kind != "ident":
                    raise ValueError(f"{where}: {t.value} needs a method name")
                mname = toks[pos + 1].value.lower()
                pos += 2
                is_global = word == "global_method"
                if pos < len(toks) and toks[pos].kind == "ident" and toks[pos].value.lower() == "global":
                    is_global = True
                    pos += 1
                if mname in self.instances:  # a named instance defined before
                    inst = self.instances[mname]
                    found.append(_Instance(inst.name, inst.method, inst.modulus * owner_modulus,
                                           inst.is_global or is_global, no, quantity_name))
                else:
                    found.append(_Instance(mname, mname, owner_modulus, is_global, no, quantity_name))
            elif word == "function":
                self.skip(no, f"quantity {quantity_name!r} defined by a function of instances (not computed)")
                log.warning("%s: quantity %r defined by a function is not computed", where, quantity_name)
                return found, len(toks)
            else:
                # instance parameters (scalar_integrand: ...) or unknown words
                self.skip(no, f"quantity/method parameter {t.value!r}")
                return found, len(toks)
        return found, pos

    def _quantity(self, toks, no):
        where = self.where(no)
        if len(toks) < 2 or toks[1].kind != "ident":
            raise ValueError(f"{where}: QUANTITY needs a name")
        name = toks[1].value
        if len(toks) == 2:  # forward declaration "quantity name;" in dumps
            return
        pos, kind, modulus = 2, None, 1.0
        while pos < len(toks):
            t = toks[pos]
            word = t.value.lower() if t.kind == "ident" else None
            if word in _QUANTITY_KINDS:
                kind = _QUANTITY_KINDS[word]
                pos += 1
                if word == "fixed" and pos < len(toks) and toks[pos].value == "=":
                    _, pos = _eval(toks, pos + 1, self.params, where)
            elif word in ("modulus", "lagrange_multiplier", "tolerance", "volconst", "target"):
                value, pos = _eval(toks, pos + 1, self.params, where)
                if word == "modulus":
                    modulus = float(value)
            elif word in ("method", "global_method", "function"):
                break
            else:
                raise ValueError(f"{where}: unexpected {t.value!r} in the definition of quantity {name!r}")
        if kind is None:
            raise ValueError(f"{where}: quantity {name!r} needs a type (energy, info_only, fixed or conserved)")
        q = _Quantity(name, kind, modulus, no)
        q.instances, pos = self._method_list(toks, pos, no, modulus, name)
        self.quantities[name.lower()] = q

    def _method_instance(self, toks, no):
        where = self.where(no)
        if len(toks) < 4 or toks[1].kind != "ident" or toks[2].value.lower() != "method":
            raise ValueError(f"{where}: expected METHOD_INSTANCE name METHOD method_name ...")
        name, method = toks[1].value, toks[3].value.lower()
        pos, modulus, is_global = 4, 1.0, False
        while pos < len(toks):
            word = toks[pos].value.lower() if toks[pos].kind == "ident" else None
            if word == "modulus":
                modulus, pos = _eval(toks, pos + 1, self.params, where)
            elif word == "global":
                is_global, pos = True, pos + 1
            elif word == "element_modulus":
                self.skip(no, f"element_modulus of method instance {name!r} (not supported)")
                raise ValueError(f"{where}: element_modulus is not supported")
            else:
                self.skip(no, f"method instance parameter {toks[pos].value!r}")
                break
        self.instances[name.lower()] = _Instance(name, method, float(modulus), is_global, no)

    # -- element sections ---------------------------------------------------------------
    def _element_id(self, toks, no, what):
        if not toks or toks[0].kind != "num" or toks[0].value != int(toks[0].value) or toks[0].value <= 0:
            raise ValueError(f"{self.where(no)}: a {what} line must start with a positive integer id")
        return int(toks[0].value)

    def _int_list(self, toks, pos):
        out = []
        while pos < len(toks) and toks[pos].kind == "num":
            v = toks[pos].value
            if v != int(v):
                break
            out.append(int(v))
            pos += 1
        return out, pos

    def _attributes(self, toks, pos, no, etype, row, flags, values):
        """Parse trailing element attributes into ``row`` (dict)."""
        where = self.where(no)
        while pos < len(toks):
            t = toks[pos]
            if t.kind != "ident":
                raise ValueError(f"{where}: unexpected {t.value!r} in a {etype} line")
            word = t.value.lower()
            pos += 1
            if word in flags:
                row.setdefault("flags", set()).add(word)
            elif word in values:
                kind = values[word]
                if kind == "expr":
                    value, pos = _eval(toks, pos, self.params, where)
                elif kind == "int":
                    value, pos = _eval(toks, pos, self.params, where)
                elif kind == "color":
                    if pos < len(toks) and toks[pos].kind == "ident" and toks[pos].value.lower() in _COLORS:
                        value, pos = _COLORS[toks[pos].value.lower()], pos + 1
                    else:
                        value, pos = _eval(toks, pos, self.params, where)
                elif kind == "ints":
                    value, pos = self._int_list(toks, pos)
                    while pos < len(toks) and toks[pos].kind == "ident" \
                            and toks[pos].value.lower() in self.constraint_names:
                        value.append(toks[pos].value.lower())
                        pos += 1
                    if not value:
                        raise ValueError(f"{where}: {word} needs at least one number")
                row[word] = value
            elif (etype, word) in self.attrs:
                size = self.attrs[(etype, word)].size
                vals = []
                if pos < len(toks) and toks[pos].kind == "op" and toks[pos].value == "{":
                    pos += 1
                    while not (pos < len(toks) and toks[pos].kind == "op" and toks[pos].value == "}"):
                        if pos >= len(toks):
                            raise ValueError(f"{where}: missing '}}' after the values of {word!r}")
                        v, pos = _eval(toks, pos, self.params, where)
                        vals.append(v)
                    pos += 1
                else:
                    for _ in range(size):
                        v, pos = _eval(toks, pos, self.params, where)
                        vals.append(v)
                if len(vals) != size:
                    raise ValueError(f"{where}: attribute {word!r} needs {size} value(s), got {len(vals)}")
                row.setdefault("extra", {})[word] = vals
            elif word in self.quantities or word in self.instances:
                if pos < len(toks) and toks[pos].kind == "op" and toks[pos].value == "-":
                    pos += 1
                row.setdefault("applied", []).append(word)
            else:
                raise ValueError(f"{where}: unknown {etype} attribute or quantity {t.value!r}")
        return row

    def _vertices(self, toks, no):
        vid = self._element_id(toks, no, "vertex")
        where = self.where(no)
        coords, pos = [], 1
        for _ in range(3):
            if pos < len(toks) and toks[pos].kind == "ident" and toks[pos].value.lower() == "boundary":
                raise ValueError(f"{where}: vertex {vid} is on a parametric boundary; such vertices "
                                 "are not supported")
            if pos >= len(toks) or toks[pos].kind == "ident" and toks[pos].value.lower() not in self.params \
                    and toks[pos].value.lower() not in _FUNCTIONS and toks[pos].value.lower() != "pi":
                raise ValueError(f"{where}: vertex {vid} needs 3 coordinates (x y z), got {len(coords)}")
            value, pos = _eval(toks, pos, self.params, where)
            coords.append(value)
        if pos < len(toks) and toks[pos].kind == "num":
            raise ValueError(f"{where}: vertex {vid} has more than 3 coordinates "
                             "(only space dimension 3 is supported)")
        row = {"id": vid, "x": coords, "line": no}
        self._attributes(toks, pos, no, "vertex", row,
                         flags={"fixed", "bare", "no_hessian_normal", "axial_point"},
                         values={"original": "int", "constraint": "ints", "constraints": "ints",
                                 "boundary": "int", "hit_partner": "int"})
        if "boundary" in row:
            raise ValueError(f"{where}: vertices on parametric boundaries are not supported")
        if "flags" in row and "axial_point" in row["flags"]:
            raise ValueError(f"{where}: axial_point vertices (symmetry groups) are not supported")
        self.vertex_rows.append(row)

    def _edges(self, toks, no):
        eid = self._element_id(toks, no, "edge")
        where = self.where(no)
        ends, pos = self._int_list(toks, 1)
        if len(ends) < 2:
            raise ValueError(f"{where}: edge {eid} needs a tail and a head vertex")
        if len(ends) > 2:
            raise ValueError(f"{where}: edge {eid} lists {len(ends)} vertices; quadratic-model midpoints "
                             "are not supported")
        row = {"id": eid, "v": ends, "line": no}
        self._attributes(toks, pos, no, "edge", row,
                         flags={"fixed", "efixed", "bare", "no_refine", "noncontent", "no_transform"},
                         values={"original": "int", "wrap": "int", "color": "color",
                                 "boundary": "int", "constraint": "ints", "constraints": "ints",
                                 "density": "expr", "tension": "expr", "orientation": "int"})
        self.edge_rows.append(row)

    def _faces(self, toks, no):
        fid = self._element_id(toks, no, "facet")
        edges, pos = self._int_list(toks, 1)
        row = {"id": fid, "e": edges, "line": no}
        self._attributes(toks, pos, no, "facet", row,
                         flags={"fixed", "nodisplay", "no_refine", "noncontent", "no_transform"},
                         values={"original": "int", "density": "expr", "tension": "expr",
                                 "boundary": "int", "constraint": "ints", "constraints": "ints",
                                 "color": "color", "frontcolor": "color", "backcolor": "color",
                                 "opacity": "expr", "phase": "int", "orientation": "int"})
        self.face_rows.append(row)

    def _bodies(self, toks, no):
        bid = self._element_id(toks, no, "body")
        facets, pos = self._int_list(toks, 1)
        row = {"id": bid, "f": facets, "line": no}
        self._attributes(toks, pos, no, "body", row, flags={"centerofmass"},
                         values={"original": "int", "volume": "expr", "volconst": "expr",
                                 "actual_volume": "expr", "pressure": "expr", "density": "expr",
                                 "phase": "int", "lagrange_multiplier": "expr"})
        self.body_rows.append(row)


# ----------------------------------------------------------------------------------------------
# Assembly of the parsed rows into an EvolverFile
# ----------------------------------------------------------------------------------------------
def _build(p: _Parser, path_label: str | None) -> EvolverFile:
    label = p.label
    if not p.vertex_rows:
        raise ValueError(f"{label}: no vertices (expected a 'vertices' section)")
    if not p.face_rows:
        raise ValueError(f"{label}: no faces (expected a 'faces' section)")
    vindex = {}
    for k, row in enumerate(p.vertex_rows):
        if row["id"] in vindex:
            raise ValueError(f"{p.where(row['line'])}: vertex {row['id']} is defined twice")
        vindex[row["id"]] = k
    edges = {}
    for row in p.edge_rows:
        if row["id"] in edges:
            raise ValueError(f"{p.where(row['line'])}: edge {row['id']} is defined twice")
        for v in row["v"]:
            if v not in vindex:
                raise ValueError(f"{p.where(row['line'])}: edge {row['id']} uses vertex {v}, which is not defined")
        edges[row["id"]] = row["v"]
        tension = row.get("density", row.get("tension", 0.0))
        if tension:
            p.skip(row["line"], f"edge {row['id']} tension {tension} (edge energy not computed)")
    # facets: vertices in Evolver order (tail of the first listed edge first)
    facet_vertices, findex = [], {}
    for k, row in enumerate(p.face_rows):
        where = p.where(row["line"])
        if row["id"] in findex:
            raise ValueError(f"{where}: facet {row['id']} is defined twice")
        findex[row["id"]] = k
        if len(row["e"]) != 3:
            raise ValueError(f"{where}: facet {row['id']} has {len(row['e'])} edges; only triangles are "
                             "supported (Evolver would subdivide it around a new central vertex)")
        oriented = []
        for s in row["e"]:
            if abs(s) not in edges:
                raise ValueError(f"{where}: facet {row['id']} uses edge {abs(s)}, which is not defined")
            a, b = edges[abs(s)]
            oriented.append((a, b) if s > 0 else (b, a))
        for j in range(3):
            if oriented[j][1] != oriented[(j + 1) % 3][0]:
                raise ValueError(f"{where}: the edges of facet {row['id']} do not form a closed loop "
                                 f"(edge {row['e'][j]} ends at vertex {oriented[j][1]}, edge "
                                 f"{row['e'][(j + 1) % 3]} starts at vertex {oriented[(j + 1) % 3][0]})")
        facet_vertices.append([vindex[a] for a, _ in oriented])
    facet_vertices = np.array(facet_vertices, dtype=np.int64)
    n_faces = len(facet_vertices)
    # body: orientation and target volume
    if len(p.body_rows) > 1:
        raise ValueError(f"{p.where(p.body_rows[1]['line'])}: {len(p.body_rows)} bodies; only one closed "
                         "body is supported")
    sign = np.ones(n_faces, dtype=np.int64)
    volume = None
    if p.body_rows:
        body = p.body_rows[0]
        where = p.where(body["line"])
        seen = set()
        for s in body["f"]:
            if abs(s) not in findex:
                raise ValueError(f"{where}: body {body['id']} uses facet {abs(s)}, which is not defined")
            if abs(s) in seen:
                raise ValueError(f"{where}: body {body['id']} lists facet {abs(s)} twice")
            seen.add(abs(s))
            sign[findex[abs(s)]] = 1 if s > 0 else -1
        missing = [row["id"] for row in p.face_rows if row["id"] not in seen]
        if missing:
            p.skip(body["line"], f"{len(missing)} facets not on body {body['id']} (first: {missing[0]})")
        volume = body.get("volume")
        for key in ("pressure", "volconst", "actual_volume"):
            if key in body:
                p.skip(body["line"], f"body {key} {body[key]}")
        if body.get("density"):
            p.skip(body["line"], f"body density {body['density']} (gravitational energy not computed)")
    faces = facet_vertices.copy()
    faces[sign < 0] = faces[sign < 0][:, [0, 2, 1]]
    # vertices: drop those on no facet (bare vertices), renumber
    used = np.zeros(len(p.vertex_rows), dtype=bool)
    used[faces.ravel()] = True
    if not used.all():
        first = p.vertex_rows[int(np.flatnonzero(~used)[0])]
        p.skip(first["line"], f"{int((~used).sum())} vertices on no facet were dropped (first: {first['id']})")
    new_index = np.cumsum(used) - 1
    faces = new_index[faces]
    vrows = [row for row, u in zip(p.vertex_rows, used) if u]
    X = np.array([row["x"] for row in vrows], dtype=np.float64)
    if not p.body_rows:
        x = X[faces]
        signed_volume = np.einsum("ij,ij->", x[:, 0], np.cross(x[:, 1], x[:, 2])) / 6.0
        if signed_volume < 0:
            faces = faces[:, [0, 2, 1]]
            sign = -sign
            p.skip(0, "no body: facets are oriented inwards, the mesh faces were reversed")
    try:
        mesh = Mesh.from_arrays(X, faces)
    except ValueError as exc:
        raise ValueError(f"{label}: the facets do not form a closed oriented surface: {exc}") from None
    # facet attributes
    tension = np.array([row.get("density", row.get("tension", 1.0)) for row in p.face_rows], dtype=np.float64)
    poisson = form = None
    if ("facet", "poisson_ratio") in p.attrs:
        poisson = np.array([row.get("extra", {}).get("poisson_ratio", [0.0])[0] for row in p.face_rows])
    if ("facet", "form_factors") in p.attrs:
        if p.attrs[("facet", "form_factors")].size != 3:
            raise ValueError(f"{label}: facet attribute form_factors must be real[3]")
        form = np.array([row.get("extra", {}).get("form_factors", [0.0, 0.0, 0.0]) for row in p.face_rows],
                        dtype=np.float64)
        form[sign < 0] = form[sign < 0][:, ::-1]
    h_zero = None
    if ("vertex", "h_zero") in p.attrs:
        h_zero = np.array([row.get("extra", {}).get("h_zero", [0.0])[0] for row in vrows], dtype=np.float64)
    elif "h_zero" in p.params:
        h_zero = float(p.params["h_zero"])
    fixed = np.array(["fixed" in row.get("flags", ()) for row in vrows])
    for (etype, name), attr in p.attrs.items():
        if (etype, name) not in {("facet", "poisson_ratio"), ("facet", "form_factors"), ("vertex", "h_zero")}:
            p.skip(0, f"{etype} attribute {name!r} (values not kept)")
    constrained = [row for row in vrows if "constraint" in row or "constraints" in row]
    if constrained:
        p.skip(constrained[0]["line"], f"{len(constrained)} vertices on level-set constraints "
                                       "(constraints are not enforced here)")
    quantities = _quantities(p, vrows, vindex, used, new_index, findex)
    vertex_ids = np.array([row["id"] for row in vrows], dtype=np.int64)
    facet_ids = np.array([row["id"] for row in p.face_rows], dtype=np.int64)
    for a in (vertex_ids, facet_ids, sign, fixed, tension):
        a.setflags(write=False)
    return EvolverFile(path=path_label, mesh=mesh, vertex_ids=vertex_ids, facet_ids=facet_ids,
                       facet_sign=sign, fixed=fixed, facet_tension=tension, poisson_ratio=poisson,
                       form_factors=form, h_zero=h_zero, volume=None if volume is None else float(volume),
                       quantities=tuple(quantities), parameters=dict(p.params), skipped=tuple(p.skipped))


def _quantities(p: _Parser, vrows, vindex, used, new_index, findex):
    """Flatten quantities into method instances with the elements they apply to."""
    applied_v: dict = {}
    applied_f: dict = {}
    for row in p.vertex_rows:
        k = vindex[row["id"]]
        for name in row.get("applied", ()):
            if used[k]:
                applied_v.setdefault(name, []).append(int(new_index[k]))
    for row in p.face_rows:
        for name in row.get("applied", ()):
            applied_f.setdefault(name, []).append(findex[row["id"]])
    out = []
    for qkey, q in p.quantities.items():
        for inst in q.instances:
            ikey = inst.name.lower()
            verts = facets = None
            if not inst.is_global:
                verts = np.array(sorted(set(applied_v.get(qkey, []) + applied_v.get(ikey, []))), dtype=np.int64)
                facets = np.array(sorted(set(applied_f.get(qkey, []) + applied_f.get(ikey, []))), dtype=np.int64)
                if inst.method in _VERTEX_METHODS and len(facets):
                    p.skip(inst.line, f"{inst.method} of quantity {q.name!r} named on facet lines (ignored)")
                if inst.method in _FACET_METHODS and len(verts):
                    p.skip(inst.line, f"{inst.method} of quantity {q.name!r} named on vertex lines (ignored)")
            out.append(EvolverQuantity(name=q.name, kind=q.kind, method=inst.method, modulus=inst.modulus,
                                       is_global=inst.is_global,
                                       instance=None if inst.name.lower() == inst.method else inst.name,
                                       vertices=verts, facets=facets, line=inst.line))
            if q.kind == "energy" and inst.method not in _FACET_METHODS | _VERTEX_METHODS:
                p.skip(inst.line, f"energy quantity {q.name!r} with method {inst.method!r} (not computed)")
    return out


def read_evolver(path) -> EvolverFile:
    """Read a Surface Evolver datafile or dump (``.fe``, ``.dmp``) into an :class:`EvolverFile`.

    The ``read`` section is never executed (it is logged and recorded in ``skipped``). Raises
    ``ValueError`` naming the file and line for malformed or unsupported input, and
    ``FileNotFoundError`` if the file does not exist.
    """
    path = Path(path)
    text = path.read_text(errors="replace")
    p = _Parser(text, str(path), path.parent)
    p.run()
    evf = _build(p, str(path))
    for note in evf.skipped:
        log.debug("%s: skipped %s", path, note)
    return evf


# ----------------------------------------------------------------------------------------------
# Writer
# ----------------------------------------------------------------------------------------------
def _num(x) -> str:
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write the non-finite number {x!r} to an Evolver file")
    return repr(x)


def _rest_form_factors(X, faces):
    x = X[faces]
    s1, s2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    return np.stack([np.einsum("ij,ij->i", s1, s1), np.einsum("ij,ij->i", s1, s2),
                     np.einsum("ij,ij->i", s2, s2)], axis=1)


def write_evolver(path, mesh: Mesh, *, kappa: float = 1.0, c0=2.0, A: float = 1.0, nu=1.0 / 3.0,
                  form_factors=None, volume: float | None = None, title: str | None = None) -> Path:
    """Write ``mesh`` as a Surface Evolver datafile whose energy is exactly the package's model.

    The file defines (Surface Evolver 2.70 syntax):

    - ``quantity stretching energy modulus A method linear_elastic global`` with facet attributes
      ``poisson_ratio = nu`` and ``form_factors`` = the rest shape's Gram matrix
      ``(s11, s12, s22)`` in each face's vertex order (default: the shape of ``mesh`` itself,
      which is then stress free);
    - ``quantity bending energy modulus 2 kappa method star_perp_sq_mean_curvature global`` with
      ``h_zero = c0 / 2`` (a ``PARAMETER`` for a scalar ``c0``, a vertex attribute for an array),
      i.e. ``(1/2) kappa (c - c0)^2`` per area with ``c = c1 + c2``;
    - every facet with ``tension 0`` (no surface tension energy) and one body holding all facets
      with ``volume`` (default: the mesh's enclosed volume) as its target.

    Face ``f`` is written as the signed edges ``(f0 -> f1, f1 -> f2, f2 -> f0)``, so Evolver's
    facet vertex order is the mesh's and ``form_factors`` apply unchanged. Numbers are written
    with 17 significant digits (exact round trip). Returns the path written.
    """
    path = Path(path)
    X, faces = mesh.X, mesh.faces
    topo = mesh.topology
    V, F = len(X), len(faces)
    for name, val in (("kappa", kappa), ("A", A)):
        if not np.isfinite(val):
            raise ValueError(f"{name} must be a finite number, got {val!r}")
    c0 = np.asarray(c0, dtype=np.float64)
    if c0.ndim and c0.shape != (V,):
        raise ValueError(f"c0 must be a number or a ({V},) array, got shape {c0.shape}")
    nu = np.broadcast_to(np.asarray(nu, dtype=np.float64), (F,))
    if not (np.isfinite(nu).all() and (np.abs(nu) < 1).all()):
        raise ValueError("nu must be finite and in (-1, 1) (Evolver divides by 1 - nu)")
    if form_factors is None:
        form_factors = _rest_form_factors(X, faces)
    form_factors = np.asarray(form_factors, dtype=np.float64)
    if form_factors.shape != (F, 3):
        raise ValueError(f"form_factors must have shape ({F}, 3), got {form_factors.shape}")
    if volume is None:
        x = X[faces]
        volume = float(np.einsum("ij,ij->", x[:, 0], np.cross(x[:, 1], x[:, 2])) / 6.0)
    # signed edge numbers of each face side f_k -> f_{k+1}
    a = faces
    b = faces[:, [1, 2, 0]]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = topo.edges[:, 0] * V + topo.edges[:, 1]
    eid = np.searchsorted(key, lo * V + hi) + 1
    signed = np.where(a < b, eid, -eid)

    out = [f"// {title}" if title else "// Surface Evolver datafile written by shellbuckle",
           "// Shell energy: stretching (1/2) eps:K:eps (linear_elastic, 2D Young modulus A = modulus,",
           "// Poisson ratio = poisson_ratio, rest shape = form_factors) plus bending",
           "// (1/2) kappa (c - c0)^2 dA with c = c1 + c2 (star_perp_sq_mean_curvature,",
           "// modulus = 2 kappa, h_zero = c0/2). Facets have tension 0.",
           f"// kappa = {_num(kappa)}, A = {_num(A)}", ""]
    if c0.ndim == 0:
        out.append(f"PARAMETER h_zero = {_num(0.5 * float(c0))}")
    else:
        out.append("define vertex attribute h_zero real")
    out += ["define facet attribute poisson_ratio real",
            "define facet attribute form_factors real[3]", "",
            f"quantity stretching energy modulus {_num(A)} method linear_elastic global",
            f"quantity bending energy modulus {_num(2.0 * kappa)} method star_perp_sq_mean_curvature global",
            "", "vertices"]
    for v in range(V):
        line = f"{v + 1} {_num(X[v, 0])} {_num(X[v, 1])} {_num(X[v, 2])}"
        if c0.ndim:
            line += f" h_zero {_num(0.5 * c0[v])}"
        out.append(line)
    out += ["", "edges"]
    out += [f"{e + 1} {i + 1} {j + 1}" for e, (i, j) in enumerate(topo.edges)]
    out += ["", "faces"]
    for f in range(F):
        s11, s12, s22 = form_factors[f]
        out.append(f"{f + 1} {signed[f, 0]} {signed[f, 1]} {signed[f, 2]} tension 0 "
                   f"poisson_ratio {_num(nu[f])} form_factors {{{_num(s11)}, {_num(s12)}, {_num(s22)}}}")
    out += ["", "bodies"]
    ids = [str(f + 1) for f in range(F)]
    chunks = [" ".join(ids[i:i + 10]) for i in range(0, F, 10)]
    out.append("1 " + " \\\n  ".join(chunks) + f" volume {_num(volume)}")
    out.append("")
    path.write_text("\n".join(out))
    return path
