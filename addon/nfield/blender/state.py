"""Add-on wide runtime state (not saved): set by register(), read by the panels."""

#: the loader's message when the compiled module nfield._native cannot be imported, else ""
native_problem: str = ""
