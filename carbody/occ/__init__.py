"""The OCCT boundary: STEP in/out, Bezier faces, sewing and checks live here and only here.

Everything outside this subpackage works on numpy arrays; OCP is imported lazily inside the
functions of these modules so that importing carbody stays fast.
"""
from __future__ import annotations

from functools import cache


@cache
def quiet_occt() -> None:
    """Keep OCCT's transfer statistics off stdout (our stdout carries JSON)."""
    from OCP.Message import Message, Message_Gravity

    printers = Message.DefaultMessenger_s().Printers()
    for i in range(1, printers.Length() + 1):
        printers.Value(i).SetTraceLevel(Message_Gravity.Message_Fail)
