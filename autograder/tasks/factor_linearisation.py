"""The generic linearisation's assembler, built once and called twice on one pattern
(``checks/factor_linearisation.py``)."""

import numpy as np

from autograder.tasks.common import each_assembly, stub_todo


def assemble_task(dims, keys, fixed, calls, impl):
    """``factor_linearisation.BlockSparseAssembler(dims, keys, fixed)``, then ``assemble(blocks)`` for each
    ``blocks`` of ``calls`` (per group ``(r, [J_a])``). Fields: as ``autograder.tasks.common.assemble_each``."""
    cls = impl.module("factor_linearisation").BlockSparseAssembler
    keys = [np.array(k, dtype=np.int64) for k in keys]
    try:
        assembler = cls(np.array(dims, dtype=np.int64), keys, np.array(fixed, dtype=np.int64))
    except NotImplementedError as exc:
        todo = stub_todo(lambda: cls.assemble(object.__new__(cls), calls[0]))
        raise NotImplementedError(f"{exc}; {todo}" if todo else str(exc)) from None
    arguments = [([(np.array(r), [np.array(J) for J in blocks]) for r, blocks in groups],) for groups in calls]
    return each_assembly(assembler, arguments)
