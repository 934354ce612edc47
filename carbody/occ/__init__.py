"""The OCCT boundary: STEP in/out, Bezier faces, sewing and checks live here and only here.

Everything outside this subpackage works on numpy arrays; OCP is imported lazily inside the
functions of these modules so that importing carbody stays fast.
"""
from __future__ import annotations

from functools import cache


@cache
def quiet_occt() -> None:
    """Keep OCCT's messages off stdout (our stdout carries JSON): its transfer statistics, and
    its own report of a file it cannot parse, which the caller says in one line instead."""
    from OCP.Message import Message

    Message.DefaultMessenger_s().ChangePrinters().Clear()
