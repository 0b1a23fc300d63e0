"""Fields by dotted name: typed overrides (``override``), a moved field's current name, and a config to and from
JSON-ready dicts (``to_dict``, ``from_dict``; ``diff`` between two)."""

from __future__ import annotations

import dataclasses
import typing
from typing import Any

from metapg_jax import strategy
from metapg_jax.config.schema import CORE_GROUPS, Config, DDPGConfig, EnvConfig, RunConfig

def _field_types(cls) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _coerce(value: Any, typ: Any, name: str) -> Any:
    """Converts a CLI string (or a Python value) to the field's declared type."""
    origin = typing.get_origin(typ)
    if typ is bool:
        if isinstance(value, bool):
            return value
        s = str(value).lower()
        if s in ("1", "true", "yes", "on"):
            return True
        if s in ("0", "false", "no", "off"):
            return False
        raise ValueError(f"{name}: expected a boolean, got {value!r}")
    if typ in (int, float, str):
        try:
            if typ is int and isinstance(value, str):
                return int(float(value)) if float(value).is_integer() else int(value)
            return typ(value)
        except (TypeError, ValueError):
            raise ValueError(f"{name}: expected {typ.__name__}, got {value!r}") from None
    if origin is tuple:
        if isinstance(value, str):
            value = [v for v in value.replace("(", "").replace(")", "").split(",") if v.strip()]
        return tuple(_coerce(v, typing.get_args(typ)[0], name) for v in value)
    raise ValueError(f"{name}: cannot set a field of type {typ}")


def current_name(dotted: str) -> str:
    """The current name of a dotted field (a field that moved out of a strategy's group keeps its old name)."""
    return strategy.moved_fields().get(dotted, dotted)


def override(cfg: Config, overrides: dict[str, Any]) -> Config:
    """Returns ``cfg`` with dotted fields replaced, e.g. ``{'ddpg.tau': '0.005'}``."""
    groups = {*CORE_GROUPS, *(k for k, _ in cfg.groups), *strategy.groups()}
    for dotted, value in overrides.items():
        dotted = current_name(dotted)
        parts = dotted.split(".")
        if len(parts) == 1 and parts[0] in ("preset", "student"):
            cfg = dataclasses.replace(cfg, **{parts[0]: _coerce(value, str, dotted)})
            continue
        if len(parts) != 2 or parts[0] not in groups:
            raise ValueError(f"unknown config field {dotted!r}; groups: {', '.join(sorted(groups))}")
        group = getattr(cfg, parts[0])
        types = _field_types(type(group))
        if parts[1] not in types:
            raise ValueError(f"unknown config field {dotted!r}; fields of {parts[0]}: {', '.join(types)}")
        group = dataclasses.replace(group, **{parts[1]: _coerce(value, types[parts[1]], dotted)})
        cfg = cfg.replace(**{parts[0]: group})
    return cfg


def to_dict(cfg: Config) -> dict[str, Any]:
    """The config as plain JSON-able nested dicts (tuples become lists): the core groups, every strategy group
    by name, ``preset`` and ``student``."""
    d = {"env": cfg.env, "run": cfg.run, "ddpg": cfg.ddpg, **dict(cfg.groups)}
    out = {k: dataclasses.asdict(v) for k, v in d.items()}
    return json_roundtrip({**out, "preset": cfg.preset, "student": cfg.student})


def json_roundtrip(obj: Any) -> Any:
    import json

    return json.loads(json.dumps(obj))


def from_dict(d: dict[str, Any]) -> Config:
    """Inverse of ``to_dict`` (used to resume a run from its stored config). A stored field that has since
    moved (``strategy.moved_fields``) is read into its new place; a group stored without one of today's
    fields gets the field's default."""
    known = strategy.groups()
    core = {"env": EnvConfig, "run": RunConfig, "ddpg": DDPGConfig}
    values: dict[str, dict] = {k: dict(v) for k, v in d.items() if isinstance(v, dict)}
    for old, new in strategy.moved_fields().items():
        group, field = old.split(".")
        if field in values.get(group, {}):
            value = values[group].pop(field)
            g2, f2 = new.split(".")
            values.setdefault(g2, {}).setdefault(f2, value)
    unknown = [k for k in values if k not in core and k not in known]
    if unknown:
        raise ValueError(f"stored config has a group {unknown[0]!r} that no registered strategy declares "
                         f"(load its plug-in first: --plugin)")

    def build(name: str, cls: type) -> Any:
        types = _field_types(cls)
        stray = set(values[name]) - set(types)
        if stray:
            raise ValueError(f"stored config has unknown fields {sorted(stray)} in group {name!r}")
        return cls(**{k: _coerce(v, types[k], f"{name}.{k}") for k, v in values[name].items()})

    fields = {name: build(name, cls) for name, cls in core.items() if name in values}
    groups = tuple((name, build(name, cls) if name in values else cls()) for name, (cls, _) in known.items())
    top = {k: d[k] for k in ("preset", "student") if k in d}
    return Config(**fields, groups=groups, **top)


def diff(a: dict[str, Any], b: dict[str, Any], prefix: str = "") -> list[str]:
    """Dotted names of the fields whose values differ between two ``to_dict`` results."""
    out = []
    for k in sorted(set(a) | set(b)):
        name = f"{prefix}{k}"
        va, vb = a.get(k), b.get(k)
        if isinstance(va, dict) and isinstance(vb, dict):
            out.extend(diff(va, vb, name + "."))
        elif va != vb:
            out.append(f"{name} ({va!r} -> {vb!r})")
    return out
