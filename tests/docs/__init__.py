"""The docs test: the code blocks and shell commands of README.md and docs/*.md run, the module paths they
name import, and the defaults they quote are the code's (the convention: docs/architecture.md, "Docs that
are executed")."""
