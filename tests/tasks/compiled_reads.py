"""The console's compiled ticks' reads of a state (``console/chunk_kernel.py``), called on a
simulation's ``mjData`` as the chunk calls them, for the tests to hold against the Python
probes."""

import numpy as np

from davinci_sim.sim import live_period


def _addresses(data) -> tuple[np.ndarray, int]:
    """The kernel's ``address`` array (the entries these reads use) and the contacts'
    stride, bytes (the state must have a contact)."""
    assert data.ncon > 0
    address = np.zeros(14, dtype=np.intp)
    address[6] = live_period.contact_count_address(data)
    address[9], address[13] = data.contact.geom.ctypes.data, data.contact.flex.ctypes.data
    address[10:13] = [data.xpos.ctypes.data, data.xmat.ctypes.data, data.site_xpos.ctypes.data]
    return address, int(data.contact.geom.strides[0])


def objects_read(probe, data):
    """``ObjectsProbe.read`` as the kernel reads it after a step: ``(xpos, xmat, grasp,
    tips, flex_force)`` (the force on the probe's flex as the kernel measures it with the
    contacts)."""
    from davinci_sim.console.chunk_slots import contacts_measure
    from davinci_sim.console.chunk_slots import objects_read as _objects_read

    address, stride = _addresses(data)
    k, a = len(probe.bodies), len(probe.tips)
    out = (np.empty((k, 3)), np.empty((k, 9)), np.empty(k, dtype=np.int64), np.empty((a, 3)))
    _objects_read(address, stride, np.asarray(probe.bodies, dtype=np.intp), probe.object_of,
                  probe.jaw_bit, np.asarray(probe.tips, dtype=np.intp), *out)  # fmt: skip
    model = probe._model
    none = np.full(model.ngeom + 1, -1, dtype=np.intp)  # (no instruments: the flex alone)
    on_flex = np.zeros(1)
    contacts_measure(model._address, data._address, address, stride, none, none,
                     np.zeros(model.ngeom + 1, dtype=bool), probe.flex, np.zeros(6), 0,
                     np.zeros(1, dtype=np.int64), np.zeros(1), on_flex)  # fmt: skip
    return (*out, float(on_flex[0]))


def stops_on_contact(data, contacts) -> bool:
    """Whether the kernel, not measuring the contacts, leaves the tick's post-steps to
    Python for the contacts now (the instrument of ``contacts``, an
    ``InstrumentContacts``)."""
    from davinci_sim.console.chunk_slots import tool_contacts as _tool_contacts

    address, stride = _addresses(data)
    return bool(_tool_contacts(address, stride, np.ones(1, dtype=bool), contacts.tool_geom,
                               contacts.other_geom))  # fmt: skip


def contacts_measured(model, data, contacts, flex: int) -> tuple[int, float, float]:
    """The kernel's measure of the contacts now: the instruments' (of ``contacts``, an
    ``InstrumentContacts``) number and force, N, and the force on the flex ``flex`` (its id;
    −1: none), N."""
    from davinci_sim.console.chunk_slots import contacts_measure

    address, stride = _addresses(data)
    count, force, on_flex = np.zeros(1, dtype=np.int64), np.zeros(1), np.zeros(1)
    contacts_measure(model._address, data._address, address, stride,
                     np.ascontiguousarray(contacts.tool_of, dtype=np.intp),
                     np.ascontiguousarray(contacts.arm_of, dtype=np.intp),
                     np.ascontiguousarray(contacts.counts, dtype=bool), flex, np.zeros(6), 0,
                     count, force, on_flex)  # fmt: skip
    return int(count[0]), float(force[0]), float(on_flex[0])
