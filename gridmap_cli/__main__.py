"""``python -m gridmap_cli`` runs the command line."""

from gridmap_cli.cli import main

main()
