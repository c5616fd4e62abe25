"""The domain of labelled surfaces as a CSG expression: ``-`` difference, ``+`` union, ``&`` intersection and
parentheses over surface names, parsed once and evaluated by min/max of the surfaces' implicit values, a
difference keeping a thinnest wall where two independently fitted surfaces cross."""
from __future__ import annotations

import re

import numpy as np

from ...errors import InvalidInputError
from .cardiac import BIVME_DEFAULT_DOMAIN

_TOKEN = re.compile(r"\s*(?:(?P<name>[A-Za-z0-9_.:]+)|(?P<op>[-+&()]))")


def parse_domain(expression: str, known) -> tuple:
    """Parse a CSG expression of surface names into a tree.

    Grammar: ``expr := term (('+' | '-') term)*``, ``term := atom ('&' atom)*``, ``atom := NAME | '(' expr ')'``;
    ``-`` is the difference, ``+`` the union, ``&`` the intersection (binding tighter), left-associative:
    ``EPI - LV_ENDO - RV_ENDO`` is ``(EPI - LV_ENDO) - RV_ENDO``.  Names are letters, digits, ``_``, ``.``, ``:``.

    Returns
    -------
    tree of tuples: ``("name", NAME)`` or ``(op, left, right)`` with op one of ``-``, ``+``, ``&``

    Raises
    ------
    InvalidInputError
        On a syntax error (the message shows where) or a name that is not in ``known`` (the message lists them).
    """
    if not isinstance(expression, str) or not expression.strip():
        raise InvalidInputError(f"domain must be a non-empty expression such as {BIVME_DEFAULT_DOMAIN!r}, got "
                                f"{expression!r}")
    known = list(known)
    tokens, position = [], 0
    text = expression.rstrip()
    while position < len(text):
        match = _TOKEN.match(text, position)
        if not match:
            raise InvalidInputError(
                f"domain {expression!r}: unexpected character {text[position:].lstrip()[:1]!r} at position "
                f"{len(text[:position]) + len(text[position:]) - len(text[position:].lstrip())}; use surface "
                "names, '-', '+', '&' and parentheses")
        tokens.append((match.group("name") and "name" or match.group("op"), match.group("name") or match.group("op"),
                       match.start(match.lastgroup)))
        position = match.end()
    tokens.append(("end", "", len(text)))
    at = 0

    def fail(message):
        where = tokens[at][2]
        raise InvalidInputError(f"domain {expression!r}: {message} at position {where}\n    {expression}\n"
                                f"    {' ' * where}^")

    def atom():
        nonlocal at
        kind, value, _ = tokens[at]
        if kind == "name":
            if value not in known:
                raise InvalidInputError(
                    f"domain {expression!r} names the unknown surface {value!r}; known surfaces: "
                    f"{', '.join(known) or '(none)'}")
            at += 1
            return ("name", value)
        if kind == "(":
            at += 1
            tree = expr()
            if tokens[at][0] != ")":
                fail("expected ')'")
            at += 1
            return tree
        fail("expected a surface name or '('" if kind != "end" else "the expression ends too early")

    def term():
        nonlocal at
        tree = atom()
        while tokens[at][0] == "&":
            at += 1
            tree = ("&", tree, atom())
        return tree

    def expr():
        nonlocal at
        tree = term()
        while tokens[at][0] in "+-" and tokens[at][0] != "end":
            op = tokens[at][0]
            at += 1
            tree = (op, tree, term())
        return tree

    tree = expr()
    if tokens[at][0] != "end":
        fail(f"unexpected {tokens[at][1]!r}")
    return tree


def domain_names(tree) -> list:
    """The surface names a parsed domain uses, in order of first use."""
    if tree[0] in ("name", "grow"):
        return [tree[1]]
    return list(dict.fromkeys(domain_names(tree[1]) + domain_names(tree[2])))


def evaluate_domain(tree, values: dict, min_wall: float = 0.0, closed=0.0):
    """The CSG value of a parsed domain and, per point, the index (into ``values``' keys) of the surface giving it.

    ``A + B = max(f_A, f_B)``, ``A & B = min(f_A, f_B)``, ``A - B = min(f_A, -f_B)``, and with ``min_wall`` = t > 0
    ``A - B = min(f_A, max(-f_B, min(t - f_A, t + f_A - f_B)))``: a point within t inside A's boundary stays in the
    domain where B reaches less than t beyond A's boundary (f_B - f_A < t, f_B - f_A being about how far B's
    boundary lies beyond A's).  Where two independently interpolated surfaces (a thin RV free wall's epicardium
    and endocardium) cross between slices, the wall keeps the thickness t instead of opening in a hole; where B
    leaves A by more, nothing is added.  ``closed`` (a float or (m,) floats >= 0, inf allowed) keeps the shell
    where B reaches up to t + closed beyond A (a heart below its base, where a cavity never opens through its wall:
    the base opens it).  The shell's inner boundary is the offset of A's, attributed to B (the cavity's wall).  A
    node ``("grow", name, t)`` (built by :func:`labelled_implicit`, not parsed) is f_name + t: the region grown by t
    (f_name about a signed distance; t None: ``min_wall``).
    """
    names = list(values)

    def walk(node):
        if node[0] in ("name", "grow"):
            value = values[node[1]]
            if node[0] == "grow":   # ("grow", name, thickness or None for min_wall)
                value = value + (min_wall if node[2] is None else node[2])
            return value, np.full(len(value), names.index(node[1]))
        (left, left_source), (right, right_source) = walk(node[1]), walk(node[2])
        if node[0] == "-":
            right = -right
            if min_wall > 0:   # right is -f_B here
                shell = np.minimum(min_wall - left, min_wall + closed + left + right)
                right = np.maximum(right, shell)
        take_right = right > left if node[0] == "+" else right < left
        return np.where(take_right, right, left), np.where(take_right, right_source, left_source)

    return walk(tree)
