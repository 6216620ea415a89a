"""The console's compiled ticks' reads of a state (``console/chunk_kernel.py``), called on a
simulation's ``mjData`` as the chunk calls them, for the tests to hold against the Python
probes."""

import numpy as np

from davinci_sim.sim import live_period


def _addresses(data) -> tuple[np.ndarray, int]:
    """The kernel's ``address`` array (the entries these reads use) and the contacts'
    stride, bytes (the state must have a contact)."""
    assert data.ncon > 0
    address = np.zeros(13, dtype=np.intp)
    address[6] = live_period.contact_count_address(data)
    address[9] = data.contact.geom.ctypes.data
    address[10:] = [data.xpos.ctypes.data, data.xmat.ctypes.data, data.site_xpos.ctypes.data]
    return address, int(data.contact.geom.strides[0])


def objects_read(probe, data):
    """``ObjectsProbe.read`` as the kernel reads it after a step: ``(xpos, xmat, grasp,
    tips)``."""
    from davinci_sim.console.chunk_slots import objects_read as _objects_read

    address, stride = _addresses(data)
    k, a = len(probe.bodies), len(probe.tips)
    out = (np.empty((k, 3)), np.empty((k, 9)), np.empty(k, dtype=np.int64), np.empty((a, 3)))
    _objects_read(address, stride, np.asarray(probe.bodies, dtype=np.intp), probe.object_of,
                  probe.jaw_bit, np.asarray(probe.tips, dtype=np.intp), *out)  # fmt: skip
    return out


def stops_on_contact(data, contacts, flex: bool) -> bool:
    """Whether the kernel leaves the tick's post-steps to Python for the contacts now (the
    instrument of ``contacts``, an ``InstrumentContacts``; ``flex``: any contact with a
    flex too)."""
    from davinci_sim.console.chunk_slots import tool_contacts as _tool_contacts

    address, stride = _addresses(data)
    return bool(_tool_contacts(address, stride, np.ones(1, dtype=bool), contacts.tool_geom,
                               contacts.other_geom, flex))  # fmt: skip
