"""Re-export of :mod:`hqp.model.layout` (the decision-variable layout), its old path."""

from hqp.model.layout import ContactSlot, ContactType, Layout

__all__ = ["ContactSlot", "ContactType", "Layout"]
