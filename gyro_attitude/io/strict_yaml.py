"""The one YAML loader for every YAML text the package reads itself (scene files, a bag's
``metadata.yaml``, the ``offered_qos_profiles`` of a recording's channels).

It is PyYAML's ``SafeLoader`` with three changes a hand-written file needs:

- **aliases are refused** while the document is composed, before any value exists: a
  521-byte file of nested anchors, nine references per level, stands for 9**9 values, and
  anything that formats, copies or walks it (an error message's ``{v!r}``) would run until
  the machine gives out. Anchors without aliases are harmless and accepted; merge keys
  (``<<: *base``) need an alias and are refused with it;
- **duplicate keys are refused** (PyYAML keeps the last one silently);
- **numbers as YAML 1.2 writes them**: ``1.0e6``, ``1e-3`` and ``6.02E23`` are floats
  (YAML 1.1, PyYAML's dialect, reads an exponent without a sign, or without a dot, as a
  string).

Errors are :class:`ValueError` with the line and column of the offending node.
"""

from __future__ import annotations

import re

import yaml

__all__ = ["load_yaml", "dump_yaml"]

# YAML 1.2 core schema float (without the .inf/.nan forms, which SafeLoader already reads):
# digits with an optional fraction and an optional exponent, signed or not.
_YAML12_FLOAT = re.compile(r"^[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?$")


class _StrictLoader(yaml.SafeLoader):
    """SafeLoader refusing aliases and duplicate keys, reading YAML 1.2 floats."""

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(
                None, None, f"YAML aliases (*{event.anchor}) are not accepted: write the "
                            "value out", event.start_mark)
        return super().compose_node(parent, index)

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen = set()
            for key_node, _ in node.value:
                if isinstance(key_node, yaml.ScalarNode):
                    key = (key_node.tag, key_node.value)
                    if key in seen:
                        raise yaml.constructor.ConstructorError(
                            None, None, f"duplicate key {key_node.value!r}",
                            key_node.start_mark)
                    seen.add(key)
        return super().construct_mapping(node, deep=deep)


# Own copy of the resolver table: adding to it must not change yaml.SafeLoader for others.
_StrictLoader.yaml_implicit_resolvers = {
    k: list(v) for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
# Appended after SafeLoader's own resolvers: ints stay ints ("42"), only what 1.1 left a
# string becomes a float.
_StrictLoader.add_implicit_resolver("tag:yaml.org,2002:float", _YAML12_FLOAT,
                                    list("-+0123456789."))


def load_yaml(text: str, what: str = "YAML"):
    """The data of one YAML document ``text``; ``ValueError`` starting with ``what`` on a
    syntax error, an alias, a duplicate key or nesting too deep to parse."""
    try:
        return yaml.load(text, Loader=_StrictLoader)  # a SafeLoader subclass
    except yaml.YAMLError as exc:
        raise ValueError(f"{what}: not valid YAML: {' '.join(str(exc).split())}") from None
    except RecursionError:
        raise ValueError(f"{what}: not valid YAML: nested too deeply") from None


class _PlainDumper(yaml.SafeDumper):
    """SafeDumper that writes a value used twice out twice: what the package writes must read
    back through :func:`load_yaml`, which refuses aliases."""

    def ignore_aliases(self, data) -> bool:
        return True


def dump_yaml(data, **kwargs) -> str:
    """``yaml.safe_dump`` without anchors or aliases (keys in the given order)."""
    kwargs.setdefault("sort_keys", False)
    return yaml.dump(data, Dumper=_PlainDumper, **kwargs)
