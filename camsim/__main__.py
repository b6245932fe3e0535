"""``python -m camsim`` runs the command line."""

from camsim.cli import main_entry

main_entry()
