"""``stereosim train`` for a machine that has torch and a GPU but not stereosim's installed
dependencies (a lent GPU image without plyfile, pyvcd, ...): the same subcommand, its one-line
errors and exit status 2, without the full command line's imports.

    PYTHONPATH=DIR_HOLDING_A_stereosim_LINK python3 benchmarks/gpu_train.py train --device cuda ...

benchmarks/gpu_sweep.sh runs it.
"""

import argparse
import sys

from stereosim.core.errors import UserError
from stereosim.sim import train_cli


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="gpu_train.py")
    train_cli.register(ap.add_subparsers(dest="command", required=True))
    args = ap.parse_args(argv)
    try:
        return args.func(args)
    except UserError as err:
        print(f"stereosim: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
