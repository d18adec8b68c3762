"""The key an override string names, read the one way every layer reads it: the config package
composing, the commands refusing keys they set themselves, the studies that run others' settings.
Like `notation`, it imports nothing of tavc's, so any layer may import it."""


def override_key(text: str) -> str:
    """The key part of an override string (everything before the first ``=``), as written."""
    return text.split("=", 1)[0].strip() or text


def setting_key(text: str) -> str:
    """The setting an override names: its key without Hydra's ``+``, ``++`` or ``~`` in front."""
    return override_key(text).lstrip("+~")
