"""Identifier rules of actuator profiles: `node_id << 5 | 0x0C`, `0x140 + node_id`, `1 << 24 | torque << 8 | node_id`.

A rule is written as the vendors' documents write it: terms joined by `|` or `+`, each a number, a parameter, a
field carried in the identifier, or one of these shifted left by a number. It becomes the runtime's parts (shift,
width, what fills them). Terms must occupy separate bits, so that `+` and `|` agree and a received identifier can be
taken apart again; a rule that needs carries, masks, multiplication or arithmetic on a parameter is refused with the
reason, rather than read some other way.
"""

from __future__ import annotations

import ast
import itertools
from dataclasses import dataclass
from typing import Any


class IdRuleError(ValueError):
    pass


@dataclass(frozen=True)
class Term:
    shift: int
    bits: int
    kind: str  # "const", "param" or "field"
    value: int | str  # the number, or the parameter's or field's name

    def span(self) -> tuple[int, int]:
        """The identifier bits the term may set: [low, high)."""
        if self.kind == "const":
            value = int(self.value)
            low = (value & -value).bit_length() - 1 if value else 0
            return self.shift + low, self.shift + value.bit_length()
        return self.shift, self.shift + self.bits

    def describe(self) -> str:
        low, high = self.span()
        what = f"0x{self.value:X}" if self.kind == "const" else f"'{self.value}'"
        return f"{what} (bits {low}..{high - 1})"

    def plain(self) -> dict[str, Any]:
        out: dict[str, Any] = {"shift": self.shift, "bits": self.bits}
        out[self.kind] = self.value
        return out


def parse_id_rule(rule: int | str, widths: dict[str, tuple[str, int]], id_bits: int) -> list[Term]:
    """The terms of an identifier rule. `widths` maps each name the rule may use to ("param" | "field", bits)."""
    if isinstance(rule, bool) or not isinstance(rule, (int, str)):
        raise IdRuleError("an identifier is a number or a rule such as 'node_id << 5 | 0x0C'")
    if isinstance(rule, int):
        terms = [_const(rule, 0)]
    else:
        try:
            tree = ast.parse(rule.strip(), mode="eval").body
        except SyntaxError:
            raise IdRuleError(f"cannot read the identifier rule {rule!r}; write terms joined by '|' or '+', such as "
                              "'node_id << 5 | 0x0C'") from None
        terms = [_term(t, widths) for t in _summands(tree)]
    terms = [t for t in terms if not (t.kind == "const" and t.value == 0)]
    ordered = sorted(terms, key=lambda t: t.span())
    for a, b in itertools.pairwise(ordered):
        if b.span()[0] < a.span()[1]:
            raise IdRuleError(f"the terms {a.describe()} and {b.describe()} overlap; netcfg combines terms that set "
                              "separate bits only (so that '+' and '|' agree and a received identifier can be taken "
                              "apart): narrow the parameter's range or split the rule")
    top = max((t.span()[1] for t in terms), default=0)
    if top > id_bits:
        raise IdRuleError(f"the identifier needs {top} bits, more than the {id_bits} of "
                          f"{'an extended' if id_bits == 29 else 'a standard'} identifier"
                          + ("; say 'extended: true' if the device uses 29-bit identifiers" if id_bits == 11 else ""))
    return terms


def rule_width(terms: list[Term]) -> int:
    return max((t.span()[1] for t in terms), default=0)


def _summands(node: ast.expr) -> list[ast.expr]:
    if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.BitOr, ast.Add)):
        return _summands(node.left) + _summands(node.right)
    return [node]


def _term(node: ast.expr, widths: dict[str, tuple[str, int]]) -> Term:
    shift = 0
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.LShift):
        if not (isinstance(node.right, ast.Constant) and type(node.right.value) is int):
            raise IdRuleError("a shift must be by a number ('node_id << 5'), not by a name")
        shift, node = node.right.value, node.left
    if isinstance(node, ast.Constant) and type(node.value) is int:
        return _const(node.value, shift)
    if isinstance(node, ast.Name):
        if node.id not in widths:
            known = ", ".join(sorted(widths)) or "none"
            raise IdRuleError(f"the identifier rule names '{node.id}', which is neither a parameter nor a field of "
                              f"this message (known: {known})")
        kind, bits = widths[node.id]
        return Term(shift, bits, kind, node.id)
    raise IdRuleError(f"cannot represent the identifier term {ast.unparse(node)!r}: a term is a number, a parameter "
                      "or a field, optionally shifted left by a number ('x << 8'); masks, multiplication and "
                      "arithmetic on parameters are not identifier rules netcfg can take apart again")


def _const(value: int, shift: int) -> Term:
    if value < 0:
        raise IdRuleError(f"an identifier term cannot be negative ({value})")
    return Term(shift, max(value.bit_length(), 1), "const", value)
