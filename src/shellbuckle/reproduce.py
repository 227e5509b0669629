"""Former name of :mod:`shellbuckle.studies.quilliet2008.reproduce`, kept for existing code.

``shellbuckle.reproduce`` is the same module object (every name, private ones included), so
imports, attribute access and monkeypatching behave as before the paper's study moved into
:mod:`shellbuckle.studies`.
"""

import sys

from .studies.quilliet2008 import reproduce as _moved

sys.modules[__name__] = _moved
