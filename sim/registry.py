"""One registry of named records, the shape every registry of softevo shares (worlds,
physics models, engines, traits, objectives, algorithms): built-in records that stay,
records added by ``register`` in the order added, lookup with an error that names the
choices."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Generic, Protocol, TypeVar


class Named(Protocol):
    name: str


T = TypeVar("T", bound=Named)


class Registry(Generic[T]):
    """Records of one ``kind`` (a word for messages, e.g. ``"world"``) by name."""

    def __init__(self, kind: str, built_in: Iterable[T]) -> None:
        self.kind = kind
        self.built_in = tuple(built_in)
        self._records: dict[str, T] = {record.name: record for record in self.built_in}

    def register(self, record: T) -> T:
        """Add ``record`` (ValueError if its name is taken)."""
        if record.name in self._records:
            raise ValueError(f"{self.kind} {record.name!r} is already registered")
        self._records[record.name] = record
        return record

    def unregister(self, name: str) -> None:
        """Remove a record ``register`` added (ValueError for a built-in one)."""
        if name in (record.name for record in self.built_in):
            raise ValueError(f"{self.kind} {name!r} is built in")
        self._records.pop(name, None)

    def get(self, name: str) -> T:
        """The record called ``name``; KeyError naming the choices."""
        try:
            return self._records[name]
        except KeyError:
            choices = ", ".join(self._records)
            raise KeyError(f"unknown {self.kind} {name!r}; choose one of {choices}") from None

    def __getitem__(self, name: str) -> T:
        """``get(name)``."""
        return self.get(name)

    def __contains__(self, name: object) -> bool:
        return name in self._records

    def names(self) -> tuple[str, ...]:
        """Every name, in registration order (the built-in ones first)."""
        return tuple(self._records)

    def records(self) -> tuple[T, ...]:
        """Every record, in registration order."""
        return tuple(self._records.values())

    def added(self) -> tuple[T, ...]:
        """The records ``register`` added."""
        built = {record.name for record in self.built_in}
        return tuple(record for record in self._records.values() if record.name not in built)
