"""The `m3c2` command line (docs/cli.md): the only layer that sees argparse and the terminal.
`main` assembles the subcommands' parsers and maps errors to exit codes."""
