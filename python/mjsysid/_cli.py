"""The `sysid` command of the installed package.

Runs the sysid program built into the package (mjsysid/bin/sysid, the same command line as the
source build's build/default/bin/sysid; docs/cli.md) with this process's arguments. Its bag import
(`sysid import` of ROS bags and MCAP files) runs this Python, which has mjsysid, unless
MJSYSID_PYTHON names another; `pip install mjsysid[bags]` brings what it needs.
"""

import os
import pathlib
import sys


def program() -> pathlib.Path:
    """The path of the sysid program inside the package."""
    return pathlib.Path(__file__).resolve().parent / "bin" / "sysid"


def main() -> None:
    """Replaces this process with the sysid program, the arguments passed on."""
    binary = program()
    if not os.access(binary, os.X_OK):
        sys.exit(f"sysid: the program {binary} is missing from the installed package mjsysid "
                 "(reinstall it: pip install --force-reinstall mjsysid)")
    os.environ.setdefault("MJSYSID_PYTHON", sys.executable)
    os.execv(str(binary), [str(binary)] + sys.argv[1:])


if __name__ == "__main__":
    main()
