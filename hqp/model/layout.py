"""The decision-variable layout of a control step.

``x = [qdd (nv) | f_1 | ... | f_k]``: joint accelerations, then one slot per
declared contact, 6 entries for a surface contact wrench and 3 for a point
contact force. Wrenches are expressed at the contact frame's origin in world
axes (pinocchio's ``LOCAL_WORLD_ALIGNED``), force first: ``f = [force, torque]``,
so ``J_c^T f`` with the ``LOCAL_WORLD_ALIGNED`` frame Jacobian ``J_c`` is their
generalized force. A contact that is not active keeps its slot (held at zero
by a top-level row), so dimensions do not change when contacts switch.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from hqp.errors import InvalidInput


class ContactType(enum.Enum):
    """Kind of contact, which fixes the size of its slot."""

    SURFACE = 6
    """Rigid surface contact: a 6D wrench ``[fx, fy, fz, tx, ty, tz]``."""
    POINT = 3
    """Point contact: a 3D force ``[fx, fy, fz]``."""


@dataclass(frozen=True)
class ContactSlot:
    """One contact's slot in the decision vector.

    Attributes:
        name: Contact name (unique in a layout).
        frame: Robot frame at which the wrench applies.
        kind: Surface (6 entries) or point (3 entries).
        start: Index of the slot's first entry in ``x``.

    """

    name: str
    frame: str
    kind: ContactType
    start: int

    @cached_property
    def size(self) -> int:
        """Number of entries of the slot."""
        return self.kind.value

    @property
    def slice(self) -> slice:
        """Slice of ``x`` that holds this contact's wrench or force."""
        return slice(self.start, self.start + self.size)


@dataclass(frozen=True)
class Layout:
    """Decision-variable layout ``x = [qdd | f_1 | ... | f_k]``.

    Attributes:
        nv: Number of joint velocities (size of ``qdd``).
        contacts: Contact slots, in order.

    """

    nv: int
    contacts: tuple[ContactSlot, ...] = field(default_factory=tuple)

    @classmethod
    def build(cls, nv: int, contacts: list[tuple[str, str, ContactType]] | None = None) -> Layout:
        """Build a layout from ``(name, frame, kind)`` triples.

        Raises:
            InvalidInput: Duplicate contact names or a non-positive ``nv``.

        """
        if nv <= 0:
            raise InvalidInput(f"Layout: nv must be positive, got {nv}")
        slots = []
        start = nv
        seen: set[str] = set()
        for name, frame, kind in contacts or []:
            if name in seen:
                raise InvalidInput(f"Layout: duplicate contact name {name!r}")
            seen.add(name)
            slots.append(ContactSlot(name, frame, ContactType(kind), start))
            start += ContactType(kind).value
        return cls(nv=nv, contacts=tuple(slots))

    @cached_property
    def n(self) -> int:
        """Total number of decision variables."""
        return self.nv + sum(c.size for c in self.contacts)

    @property
    def qdd(self) -> slice:
        """Slice of ``x`` holding the joint accelerations."""
        return slice(0, self.nv)

    def contact(self, name: str) -> ContactSlot:
        """Return the slot of a contact by name.

        Raises:
            InvalidInput: No contact of that name (lists the declared ones).

        """
        for c in self.contacts:
            if c.name == name:
                return c
        names = ", ".join(c.name for c in self.contacts) or "none"
        raise InvalidInput(f"Layout: unknown contact {name!r}; declared contacts: {names}")

    def zeros(self, rows: int = 0) -> np.ndarray:
        """Return a zero matrix ``(rows, n)``, or a zero vector ``(n,)`` when ``rows == 0``."""
        return np.zeros((rows, self.n)) if rows else np.zeros(self.n)
