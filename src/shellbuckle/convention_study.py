"""Former name of :mod:`shellbuckle.studies.quilliet2008.conventions`, kept for existing code.

``shellbuckle.convention_study`` is the same module object (every name, private ones included), so
imports, attribute access and monkeypatching behave as before the paper's study moved into
:mod:`shellbuckle.studies`.
"""

import sys

from .studies.quilliet2008 import conventions as _moved

sys.modules[__name__] = _moved
