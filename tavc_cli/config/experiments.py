"""The experiments ``tavc list`` shows: tavc's experiment files, and the experiments registered
in the chapter's registry from the user's config folders (``--config-dir``)."""

from tavc_cli.chapter import EXPERIMENTS
from tavc_cli.config.loading import list_experiments, load_config


def describe_experiments() -> list[dict]:
    """Every experiment, by name, as `list_experiments` describes tavc's own (``name``,
    ``section``, ``description``): those files, and the file of each experiment of the registry
    (`tavc_cli.chapter`) that is not among them, looked for in the user's config folders.

    Raises:
        TavcError: If an experiment file does not compose, or a registered experiment has none.
    """
    found = {item["name"]: item for item in list_experiments()}
    for name in EXPERIMENTS:
        if name not in found:
            cfg = load_config([f"experiment={name}"])
            found[name] = {"name": name, "section": cfg.section, "description": cfg.description}
    return [found[name] for name in sorted(found)]
