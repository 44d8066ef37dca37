"""The IMU register models, for the fakes' `import regmodels`: they live in hoverfly/sim/regmodels.py, which
the simulator board's I2C (maintenance commands 22-23) serves from as well."""

try:
    from hoverfly.sim.regmodels import *  # noqa: F401,F403
except ImportError:
    # A flash bundle's lib/ (the portable tests also run from one) holds no hoverfly.sim: run its source here.
    _here = __file__.rsplit("/", 1)[0] if "/" in __file__ else "."
    with open(_here + "/../../src/hoverfly/sim/regmodels.py") as _f:
        exec(_f.read(), globals())
