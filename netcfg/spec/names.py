"""The one safe alphabet of names: spec names end up as file names, C identifiers, Python keys and DBC names.

check_name is the rule (netcfg.spec.schema's Name type applies it), is_name asks it, and safe_name makes a name it
accepts from free text (EDS object names, DBC and bus.yml names). Plain Python: the importers and anything else
may use it without the spec language's pydantic models.
"""

from __future__ import annotations

import re

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,62}$")
C_KEYWORDS = frozenset(
    [
        "auto",
        "break",
        "case",
        "char",
        "const",
        "continue",
        "default",
        "do",
        "double",
        "else",
        "enum",
        "extern",
        "float",
        "for",
        "goto",
        "if",
        "inline",
        "int",
        "long",
        "register",
        "restrict",
        "return",
        "short",
        "signed",
        "sizeof",
        "static",
        "struct",
        "switch",
        "typedef",
        "union",
        "unsigned",
        "void",
        "volatile",
        "while",
        "_Bool",
        "_Complex",
        "_Imaginary",
        "_Alignas",
        "_Alignof",
        "_Atomic",
        "_Generic",
        "_Noreturn",
        "_Static_assert",
        "_Thread_local",
        "bool",
        "true",
        "false",
        "NULL",
    ]
)
CPP_KEYWORDS = frozenset(
    (
        "alignas alignof and and_eq asm bitand bitor catch char8_t char16_t char32_t class compl concept consteval "
        "constexpr constinit const_cast co_await co_return co_yield decltype delete dynamic_cast explicit export "
        "friend mutable namespace new noexcept not not_eq nullptr operator or or_eq private protected public "
        "reinterpret_cast requires static_assert static_cast template this thread_local throw try typeid typename "
        "using virtual wchar_t xor xor_eq"
    ).split()
)
# Macros of the headers generated C includes (<stdint.h>, <stdbool.h>, <string.h>) would rewrite a field name.
_STD_MACRO = re.compile(
    r"^(U?INT(8|16|32|64|_LEAST\d+|_FAST\d+|PTR|MAX)_(MAX|MIN|C)|U?INTMAX_C|SIZE_MAX|PTRDIFF_(MAX|MIN)"
    r"|SIG_ATOMIC_(MAX|MIN)|WCHAR_(MAX|MIN)|WINT_(MAX|MIN)|__bool_true_false_are_defined|assert|errno)$"
)
RESERVED_FILE_NAMES = frozenset(
    ["con", "prn", "aux", "nul"] + [f"com{i}" for i in range(1, 10)] + [f"lpt{i}" for i in range(1, 10)]
)


def check_name(value: str) -> str:
    if not _NAME.match(value):
        raise ValueError(
            f"{value!r} is not a safe name: names become file names and C identifiers, so use a letter "
            "followed by letters, digits or '_' (at most 63 characters), e.g. 'hip_right'"
        )
    if value in C_KEYWORDS or value in CPP_KEYWORDS:
        raise ValueError(f"{value!r} is a C or C++ keyword; pick another name, e.g. '{value}_node'")
    if _STD_MACRO.match(value) or value.startswith("_"):
        raise ValueError(f"{value!r} is a name the C standard headers use; pick another name")
    if value.lower() in RESERVED_FILE_NAMES:
        raise ValueError(f"{value!r} is a reserved file name on Windows; pick another name")
    return value


def is_name(value: str) -> bool:
    """Whether check_name accepts value."""
    try:
        check_name(value)
    except ValueError:
        return False
    return True


def safe_name(raw: str, prefix: str, suffix: str) -> str:
    """A name check_name accepts, made from free text (an EDS object name, a DBC or bus.yml name).

    Characters other than letters, digits and '_' become '_'; a name that does not start with a letter (a digit,
    '_', nothing at all) gets `prefix` and '_' in front; a C/C++ keyword, C header macro or reserved file name
    gets `suffix` at the end; the result has at most 63 characters. Callers that want more (lower case, runs of
    '_' collapsed) normalise raw first. prefix must itself be a name, e.g. 'sig' with suffix '_sig'.
    """
    check_name(prefix)
    name = re.sub(r"[^A-Za-z0-9_]", "_", raw)
    if not re.match(r"[A-Za-z]", name):
        name = prefix.rstrip("_") + ("" if name.startswith("_") else "_") + name
    name = name[:63]
    for candidate in (name, name[: 63 - len(suffix)] + suffix):
        if is_name(candidate):
            return candidate
    return prefix  # only for a suffix that makes matters worse, e.g. '_MAX' after 'INT8'
