import os
import sys

HERE = os.path.dirname(__file__)
sys.path.insert(0, os.path.join(HERE, "portable"))
sys.path.insert(0, HERE)
