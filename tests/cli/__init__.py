"""The command line (:mod:`camsim.cli`): in-process calls, help texts, hostile inputs, one-line errors."""
