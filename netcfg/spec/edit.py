"""Change values of a spec's messages in its own text, keeping every comment, blank line and layout.

PyYAML's composer gives each scalar's start and end in the text: a value that is there is replaced where it
stands; a missing key is added after the message's last key (flow style: `{..., id: 0x123}`) or on a line of its
own under `name:` (block style), so the rest of the file stays byte for byte as the user wrote it.
"""

from __future__ import annotations

import yaml

_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def set_message_values(text: str, values: dict[str, dict[str, str]]) -> str:
    """values: message name -> {key: YAML text of the new value}. Messages not in the text are ignored."""
    root = yaml.compose(text, Loader=_LOADER)
    edits: list[tuple[int, int, str]] = []  # (start, end, replacement), applied from the end
    messages = _child(root, "messages")
    if not isinstance(messages, yaml.SequenceNode):
        return text
    for node in messages.value:
        if not isinstance(node, yaml.MappingNode):
            continue
        keys = {k.value: (k, v) for k, v in node.value if isinstance(k, yaml.ScalarNode)}
        name = keys.get("name")
        if name is None or name[1].value not in values:
            continue
        for key, new in values[name[1].value].items():
            if key in keys:
                v = keys[key][1]
                edits.append((v.start_mark.index, v.end_mark.index, new))
            elif node.flow_style:
                last = node.value[-1][1]
                edits.append((last.end_mark.index, last.end_mark.index, f", {key}: {new}"))
            else:
                name_key, name_value = name
                eol = text.find("\n", name_value.end_mark.index)
                eol = len(text) if eol < 0 else eol
                edits.append((eol, eol, f"\n{' ' * name_key.start_mark.column}{key}: {new}"))
    for start, end, new in sorted(edits, reverse=True):
        text = text[:start] + new + text[end:]
    return text


def _child(node: yaml.Node | None, key: str) -> yaml.Node | None:
    if not isinstance(node, yaml.MappingNode):
        return None
    return next((v for k, v in node.value if isinstance(k, yaml.ScalarNode) and k.value == key), None)
