"""The parts of python/dampnet/_core.pyi that dampnet.h's X-macros define, written from the built
module's registries (issue 52: a state added by dampnet.h's recipe used to be patched into the
stub by its test alone, so the shipped stub never had it).

Generated regions, each between a `# <generated: NAME>` and a `# </generated>` line:
  DamperInput      the fields of dn_damper_input (_core.DAMPER_INPUT_FIELDS: name and doc)
  Damper.forces    its optional arrays: the fields appended after `stage` (role QTY_OPT, the
                   damper states' and any later field's; NaN when not given)

After a change to DN_DAMPER_INPUT_FIELDS (the stateful-feature recipe's step 2) and a rebuild:
    python tests/python/core_stub.py        # rewrites python/dampnet/_core.pyi
tests/python/test_core_stub.py fails, naming this command, until the stub is up to date.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

STUB = Path(__file__).resolve().parents[2] / "python" / "dampnet" / "_core.pyi"
#: dn_damper_input's integer fields (the others are dn_real)
INT_FIELDS = {"stage"}
#: the last field Damper.forces does not take as an optional array
LAST_FIXED = "stage"


def regions() -> dict[str, list[str]]:
    """Each generated region's lines, from the built module's registries."""
    from dampnet import _core

    fields = dict(_core.DAMPER_INPUT_FIELDS)
    names = list(fields)
    appended = names[names.index(LAST_FIXED) + 1:]
    return {
        "DamperInput": [f"    {n}: {'int' if n in INT_FIELDS else 'float'}  # {doc}" for n, doc in fields.items()],
        "Damper.forces": [f"        {n}: npt.ArrayLike = ...," for n in appended],
    }


def generated(stub: str) -> str:
    """The stub with every generated region rewritten; ValueError when a region's markers are missing."""
    for name, lines in regions().items():
        pattern = re.compile(rf"(?m)^([ \t]*# <generated: {re.escape(name)}>\n)(.*?)(^[ \t]*# </generated>\n)", re.S)
        if not pattern.search(stub):
            raise ValueError(f"{STUB}: no '# <generated: {name}>' ... '# </generated>' lines")
        stub = pattern.sub(lambda m: m.group(1) + "".join(x + "\n" for x in lines) + m.group(3), stub, count=1)
    return stub


if __name__ == "__main__":
    text = STUB.read_text()
    new = generated(text)
    if new != text:
        STUB.write_text(new)
        print(f"{STUB}: rewritten from dampnet._core's registries")
    else:
        print(f"{STUB}: up to date")
    sys.exit(0)
