"""The IMU register models, for the fakes' `import regmodels`: they live in hoverfly/sim/regmodels.py, which
the simulator board's I2C (maintenance commands 22-23) serves from as well."""

from hoverfly.sim.regmodels import *  # noqa: F401,F403
