"""The fixed-point kernels of the pass: the one source of the Pico's fast pass (hoverfly.fastgen generates their
viper twins; docs/fastpass.md)."""
