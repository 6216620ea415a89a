"""The web console: the surgeon's display, operator input and the simulator's GUI in a browser."""
