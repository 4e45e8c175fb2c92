"""mjsysid: system identification for MuJoCo models.

The functions and classes are those of the C++ extension module mjsysid._mjsysid (nanobind);
docs/python.md describes them. `import mujoco` and `import mjsysid` share one libmujoco.
"""

from ._mjsysid import *  # noqa: F401,F403
from ._mjsysid import __version__  # noqa: F401
