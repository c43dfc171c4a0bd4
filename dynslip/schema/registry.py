"""Registries of tagged specs: a choice in the scenario file (a friction law, a stop rule) is a
pydantic discriminated union whose variants are the registry's spec classes, one per tag.

A field annotated ``Annotated[BaseSpec, registry]`` validates a mapping by its tag (``law``,
``rule``) into that variant; a bare string is read as the variant with its defaults
(``until: rest`` is ``until: {rule: rest}``); a mapping without the tag takes the registry's
default tag where it has one; where the registry says so, another variant's parameters are
ignored, so that a file may switch the variant by ``--set`` alone. :meth:`Registry.register`
adds a variant from outside the package and rebuilds the models whose fields reach the
registry, so that the next validation knows it::

    STOP_SPECS.register(MyRuleSpec)   # MyRuleSpec: a StopSpec with rule: Literal["mine"]
"""

from __future__ import annotations

import typing
from typing import Annotated, Any, Union

from pydantic import BaseModel, Field
from pydantic_core import core_schema

from dynslip.schema.base import Strict

__all__ = ["Registry"]


class Registry:
    """Spec classes by their tag (the value of the ``tag`` field's one-value ``Literal``)."""

    def __init__(self, tag: str, default: str | None = None, others_ignored: bool = False):
        self.tag = tag
        self.default = default
        self.others_ignored = others_ignored
        self.specs: dict[str, type[BaseModel]] = {}

    def tag_of(self, spec: type[BaseModel]) -> str:
        """The tag of a spec class: its ``tag`` field's ``Literal`` value."""
        ann = spec.model_fields[self.tag].annotation
        values = typing.get_args(ann)
        if typing.get_origin(ann) is not typing.Literal or len(values) != 1:
            raise TypeError(f"{spec.__name__}.{self.tag} must be a Literal of one value, got {ann}")
        return values[0]

    def add(self, spec: type[BaseModel]) -> type[BaseModel]:
        """Record ``spec`` under its tag (a class decorator, for the package's own variants)."""
        self.specs[self.tag_of(spec)] = spec
        return spec

    def register(self, spec: type[BaseModel]) -> type[BaseModel]:
        """Add ``spec`` after the schema was built (from outside the package): the models whose
        fields reach this registry are rebuilt, innermost first. A tag already taken is an
        error."""
        tag = self.tag_of(spec)
        if tag in self.specs and self.specs[tag] is not spec:
            raise ValueError(f"{self.tag}: {tag!r} is already registered "
                             f"({self.specs[tag].__name__})")
        self.add(spec)
        _rebuild_holders()
        return spec

    def unregister(self, spec: type[BaseModel]) -> None:
        """Remove ``spec`` (added by :meth:`register`) and rebuild the models that reach it."""
        tag = self.tag_of(spec)
        if self.specs.get(tag) is spec:
            del self.specs[tag]
            _rebuild_holders()

    def __get_pydantic_core_schema__(self, source: Any, handler) -> core_schema.CoreSchema:
        specs = tuple(self.specs.values())
        union = (Annotated[Union[specs], Field(discriminator=self.tag)]  # noqa: UP007
                 if len(specs) > 1 else specs[0])
        return core_schema.no_info_before_validator_function(self._tagged,
                                                             handler.generate_schema(union))

    def _tagged(self, value: Any) -> Any:
        if isinstance(value, str):
            return {self.tag: value}
        if not isinstance(value, dict):
            return value
        if self.tag not in value and self.default is not None:
            value = {self.tag: self.default, **value}
        spec = self.specs.get(value.get(self.tag)) if isinstance(value.get(self.tag), str) else None
        if self.others_ignored and spec is not None:
            # another variant's parameters are ignored (``--set physics.friction.law=coulomb`` on
            # a file that states mu_s); a key of no variant is still refused
            others = {k for s in self.specs.values() for k in s.model_fields} - set(
                spec.model_fields)
            value = {k: v for k, v in value.items() if k not in others}
        return value


def _registries(annotation: Any, metadata: list) -> list[Registry]:
    return [m for m in metadata if isinstance(m, Registry)] + [
        m for a in typing.get_args(annotation) for m in getattr(a, "__metadata__", ())
        if isinstance(m, Registry)]


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    """The pydantic model classes named in an annotation (through lists, unions, Annotated)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for a in typing.get_args(annotation) for m in _models_in(a)]


def _rebuild_holders() -> None:
    """Rebuild every schema model whose fields reach a registry, children before parents."""

    models: list[type[BaseModel]] = []
    stack: list[type[BaseModel]] = [Strict]
    while stack:
        for sub in stack.pop().__subclasses__():
            models.append(sub)
            stack.append(sub)
    holds: dict[type[BaseModel], bool] = {}
    order: list[type[BaseModel]] = []

    def visit(m: type[BaseModel]) -> bool:
        if m in holds:
            return holds[m]
        holds[m] = False  # a cycle through m adds nothing new
        found = False
        for f in m.model_fields.values():
            regs = _registries(f.annotation, f.metadata)
            children = _models_in(f.annotation) + [s for r in regs for s in r.specs.values()]
            found = bool(regs) or found
            for c in children:
                found = visit(c) or found
        holds[m] = found
        if found:
            order.append(m)
        return found

    for m in models:
        visit(m)
    for m in order:
        m.model_rebuild(force=True)
