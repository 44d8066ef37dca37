"""The flight log: what is logged and how it is framed."""
