"""Overrides read and written the one way every layer does: the key an override string names
(the config package composing, the commands refusing keys they set themselves, the studies that
run others' settings), and the override that sets a key to a value taken to the letter (a folder
tavc derives from one the user named, whose name may hold the grammar's own characters). Like
`notation`, it imports nothing of tavc's, so any layer may import it."""

import re


def override_key(text: str) -> str:
    """The key part of an override string (everything before the first ``=``), as written."""
    return text.split("=", 1)[0].strip() or text


def setting_key(text: str) -> str:
    """The setting an override names: its key without Hydra's ``+``, ``++`` or ``~`` in front."""
    return override_key(text).lstrip("+~")


def literal(text: str) -> str:
    """`text` quoted so that Hydra's override grammar gives it back to the letter: a path may hold
    ``,`` (a sweep, unquoted), ``=``, quotes, brackets or backslashes (Hydra, in quotes, reads
    backslashes doubled only before a quote or at the end). A ``${`` stays an interpolation, as
    in every setting of tavc's."""
    text = re.sub(r"(\\*)('|$)", lambda m: m.group(1) * 2 + ("\\'" if m.group(2) else ""), text)
    return f"'{text}'"


def setting(key: str, value: object) -> str:
    """The override that sets `key` to `value`'s text, taken to the letter (`literal`)."""
    return f"{key}={literal(str(value))}"
