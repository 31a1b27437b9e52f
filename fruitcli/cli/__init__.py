"""The command line: one thin module per `fruit` subcommand (`main` lists them and imports
each on first use), and the options and error handling they share (`options`).
Library code neither prints nor exits; these modules do both.

May import every package of `fruitcli`; nothing imports it but the console script.
"""
