"""What Hydra, OmegaConf and YAML raise, as one ``TavcError`` line naming the key."""

import contextlib
import dataclasses
import difflib
import re
import shlex
from collections.abc import Callable, Iterator, Sequence
from typing import Optional

import yaml
from hydra.errors import HydraException, MissingConfigException
from omegaconf import DictConfig
from omegaconf.errors import (
    ConfigAttributeError,
    ConfigKeyError,
    OmegaConfBaseException,
    ValidationError,
)

from tavc_cli.config.folders import config_file
from tavc_cli.errors import TavcError
from tavc_cli.override_keys import setting_key

_GROUP_VALUE = "Config group override must be"  # Hydra's words for a group given null or a number


@contextlib.contextmanager
def hydra_errors(overrides: Sequence[str]) -> Iterator[None]:
    """Turn what composing with ``overrides`` may raise into one ``TavcError`` line."""
    try:
        yield
    except MissingConfigException as error:
        raise TavcError(_missing_option_message(error)) from None
    except HydraException as error:
        raise TavcError(_hydra_message(error)) from None
    except OmegaConfBaseException as error:
        raise TavcError(omegaconf_message(error)) from None
    except yaml.YAMLError as error:
        raise TavcError(_yaml_message(error)) from None
    except AssertionError as error:
        # Hydra asserts instead of raising when an override walks through a null node
        # (``team.members.0.speed_mps=1`` while ``team.members`` is null).
        raise TavcError(_null_parent_message(overrides, error)) from None
    except ValueError as error:
        # a config group given null or a number (``robot=null``, ``scale=123``)
        if _GROUP_VALUE not in str(error):
            raise
        raise TavcError(_group_value_message(overrides)) from None


def uncaught_by_hydra(error: Exception) -> bool:
    """Whether `error`, raised while composing, is one Hydra lets slip from an override or a config
    file it cannot read (a list node given a key that is no index, a group given a list, a file
    that is not UTF-8 or includes itself) rather than one of its own (`hydra_errors`)."""
    own = isinstance(error, (HydraException, OmegaConfBaseException))
    return not own and _GROUP_VALUE not in str(error)


def uncomposable_message(overrides: Sequence[str], culprit: str | None, error: Exception) -> str:
    """One line for an `uncaught_by_hydra` error: the override that does not compose even alone
    (`culprit`), or all of them."""
    why = ("nested too deeply, or a config file that includes itself" if isinstance(error, RecursionError)
           else f"{type(error).__name__}: {error}")
    if culprit is not None:
        return f"{setting_key(culprit)}: {culprit!r} cannot be applied ({why})"
    return f"the overrides {' '.join(overrides)} cannot be applied together ({why})"


def override_syntax_message(overrides: Sequence[str], index: int, error: Exception,
                            parses: Callable[[str], bool]) -> str:
    """One line for an override Hydra's grammar cannot read, with the quoting that would read it.

    A value with characters the grammar takes only in quotes (non-ASCII letters, brackets, ``#``)
    is shown quoted, as the shell must pass it (``'output_dir="/tmp/résultats"'``); a word
    without ``=`` after an override is taken for the rest of that override's value that the
    shell split off at a space (``output_dir=/tmp/my results``). `parses` says whether an
    override would parse.

    Args:
        overrides: The overrides as given.
        index: The one that does not parse.
        error: What Hydra raised for it.
        parses: Whether a rewritten override would parse.
    """
    text = overrides[index]
    key, equals, value = text.partition("=")
    key = key.strip()
    if not equals:
        first, last = index, index  # every word the shell split off the value, not only this one
        while first > 0 and "=" not in overrides[first - 1]:
            first -= 1
        while last + 1 < len(overrides) and "=" not in overrides[last + 1]:
            last += 1
        previous = overrides[first - 1] if first > 0 else ""
        before, _, start = previous.partition("=")
        joined = f"{before}={_hydra_quoted(' '.join([start, *overrides[first:last + 1]]))}"
        if "=" in previous and parses(joined):
            return (f"{text}: not an override (key=value); if it is the rest of {before}'s value, cut off at a "
                    f"space, quote the whole override: {shlex.quote(joined)}")
        return f"{text}: not an override (key=value); to set a key, write {text}=<value>"
    quoted = f"{key}={_hydra_quoted(value)}"
    if parses(quoted):
        where = _offending(text, error)
        which = f" ({where!r})" if where else ""
        return (f"{key}: the value {value!r} has a character Hydra's override grammar reads only in quotes{which}; "
                f"quote it: {shlex.quote(quoted)}")
    return f"{key or text}: cannot parse override {text!r} ({hydra_detail(error)})"


def _hydra_quoted(value: str) -> str:
    """`value` as a quoted string of Hydra's override grammar."""
    if '"' not in value:
        return f'"{value}"'
    if "'" not in value:
        return f"'{value}'"
    return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _offending(text: str, error: Exception) -> str:
    """The character of `text` Hydra stopped at, where its message shows it."""
    lines = str(error).splitlines()
    lexer = "LexerNoViableAltException: "
    if len(lines) > 1 and lines[0].startswith(lexer) and "^" in lines[1]:
        column = lines[1].index("^") - len(lexer)
        if 0 <= column < len(text):
            return text[column]
    mismatched = re.match(r"mismatched input '(.+?)'", lines[0] if lines else "")
    return mismatched.group(1) if mismatched else ""


def _null_parent_message(overrides: Sequence[str], error: AssertionError) -> str:
    """``team.members.0.speed_mps: team.members is null here; give the whole list ...``."""
    for override in overrides:
        key = setting_key(override)
        parts = key.split(".")
        index = next((i for i, part in enumerate(parts) if part.isdigit()), None)
        if index:
            parent = ".".join(parts[:index])
            return (f"{key}: {parent} is null in this config, so it has no element {parts[index]}; "
                    f"give the whole list ({parent}=[...])")
    return f"cannot apply overrides {' '.join(overrides)} (is a parent key null?): {error}"


def _group_value_message(overrides: Sequence[str]) -> str:
    """``robot: a config group takes the name of one of its options, got null``."""
    for override in overrides:
        key, _, value = override.partition("=")
        key = key.lstrip("+~")
        if not key:
            return f"{override}: an override needs a key (key=value)"
        if "." not in key and "/" not in key and (value in ("null", "") or _is_number(value)):
            return f"{key}: a config group takes the name of one of its options, got {value or 'nothing'}"
    return f"a config group takes the name of one of its options: {' '.join(overrides)}"


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def hydra_detail(error: Exception) -> str:
    """The informative lines of a Hydra error, without its boilerplate, as one line."""
    lines = []
    for line in str(error).splitlines():
        line = line.strip()
        if not line or line.startswith(("See https://", "Error parsing override")):
            continue
        lines.append(line.split(" expecting {")[0])
    return "; ".join(lines) or type(error).__name__


def _yaml_message(error: yaml.YAMLError) -> str:
    """``conf/arena/x.yaml:3: invalid YAML (expected ',' or ']' ...)``."""
    mark = getattr(error, "problem_mark", None)
    where = f"{mark.name}:{mark.line + 1}" if mark is not None else "config"
    problem = getattr(error, "problem", None) or type(error).__name__
    return f"{where}: invalid YAML ({problem})"


def _missing_option_message(error: MissingConfigException) -> str:
    """``arena=nope: no such option; choose one of one_circuit, two_circuits``."""
    missing = error.missing_cfg_file or ""
    if "/" not in missing:
        return f"config: {hydra_detail(error).split(';')[0]}"
    group, option = missing.rsplit("/", 1)
    if error.options:
        return f"{group}={option}: no such option; choose one of {', '.join(error.options)}"
    return f"{group}={option}: could not load {missing!r}"


def _hydra_message(error: HydraException) -> str:
    """A composition error, reported against the override or config file that caused it."""
    text = str(error)
    in_file = re.match(r"In '([^']+)': \w+ raised while composing config:\n(.*)", text)
    if in_file:
        # A config file itself is wrong (e.g. a key the schema lacks); name the key and file.
        full_key = re.search(r"full_key: (\S+)", text)
        key = full_key.group(1) if full_key else "config"
        return f"{key}: {_validation_detail(in_file.group(2))} (in {config_file(in_file.group(1))})"
    twice = re.search(r"Multiple values for (\S+?)\.(?:\s|$)", text) or re.match(  # a group given again with a +
        r"(\S+) appears more than once in the final defaults list", text)
    if twice:
        return (f"{twice.group(1)}: a config group holds one option, and it was given two; choose it once, "
                f"without a + (which adds a second): {twice.group(1)}=<option>")
    match = re.search(r"(?<!To )override '?([^'=\s]+)", text)
    context = match.group(1) if match else None
    if isinstance(error.__cause__, OmegaConfBaseException):
        return omegaconf_message(error.__cause__, context=context)
    detail = text.splitlines()[0] if text else type(error).__name__
    return f"{context}: {detail}" if context else detail


def omegaconf_message(error: OmegaConfBaseException, context: Optional[str] = None) -> str:
    """One line naming the key for an OmegaConf key or type error.

    Args:
        error: The OmegaConf exception.
        context: The override key being applied, if known. An element of a list literal (a
            breakdown dict, say) reports its key without the path, so the override names it.
    """
    full_key = getattr(error, "full_key", None) or ""
    nested = bool(context) and not full_key.startswith(context.split(".")[0])
    where = context if nested or not full_key else full_key
    if isinstance(error, (ConfigKeyError, ConfigAttributeError)):
        if where.startswith("learner.params.") and where.count(".") == 2:
            # a learner's parameters are what its YAML lists; one more is added with `+`, then
            # checked against the class's signature (`learning.plugins.check_params`)
            return (f"{where}: the learner's config lists no such parameter; to give one it does not list, "
                    f"add it with a plus: +{where}=...")
        if where.startswith("learner.") and where.count(".") == 1:
            # a learner's node holds exactly the parameters its settings class declares
            return f"{where}: {_learner_hint(error)}"
        unknown = f"unknown key {error.key!r}" if nested else "unknown key"
        return f"{where}: {unknown}{_key_hint(error)}"
    if isinstance(error, ValidationError):
        return f"{where}: {_validation_detail(str(error))}"
    detail = str(error).splitlines()[0] if str(error) else type(error).__name__
    return f"{where or 'config'}: {detail}"


# a learner's node beside its parameters: what it is and where a plugin's own parameters go
_LEARNER_FRAME = ("name", "target", "params")


def _learner_hint(error: OmegaConfBaseException) -> str:
    """Why a `learner.<key>` override is refused: the chosen learner (named where its node says)
    takes no such parameter, and the ones it takes, the nearest first if one is near; a learner
    from `learner.target` takes its own under `learner.params`."""
    node = getattr(error, "parent_node", None)
    name, target, taken, own = None, None, [], []
    if isinstance(node, DictConfig):
        try:
            name, target, params = node.get("name"), node.get("target"), node.get("params")
            taken = [str(k) for k in node.keys() if str(k) not in _LEARNER_FRAME]
            own = [str(k) for k in params.keys()] if isinstance(params, DictConfig) else []
        except Exception:  # a missing value or an interpolation in the node: the message stays general
            name, target, taken, own = None, None, [], []
    who = f"the learner {name}" if isinstance(name, str) and name else "the chosen learner"
    key = str(error.key)
    if target:
        close = difflib.get_close_matches(key, own, n=1)
        near = f" (did you mean learner.params.{close[0]}?)" if close else ""
        return f"{who} comes from learner.target and takes its parameters as learner.params.<key>{near}"
    close = difflib.get_close_matches(key, taken, n=1)
    near = f"did you mean {close[0]!r}? " if close else ""
    return f"{who} takes no parameter {key} ({near}it takes {', '.join(taken) or 'no parameters'})"


def _key_hint(error: OmegaConfBaseException) -> str:
    """Suggest the closest valid key, or list the valid keys."""
    object_type = getattr(error, "object_type", None)
    if not dataclasses.is_dataclass(object_type):
        return ""
    names = [item.name for item in dataclasses.fields(object_type)]
    close = difflib.get_close_matches(str(error.key), names, n=1)
    return f" (did you mean {close[0]!r}?)" if close else f"; valid keys: {', '.join(names)}"


def _validation_detail(text: str) -> str:
    """Rephrase OmegaConf's type errors as ``expected an integer, got 'abc'``."""
    first = text.strip().splitlines()[0] if text.strip() else "invalid value"
    match = re.match(r"Value '(.*)' of type '\w+' could not be converted to (\w+)", first)
    if match:
        kinds = {"Integer": "an integer", "Float": "a number", "Boolean": "true or false"}
        return f"expected {kinds.get(match.group(2), match.group(2))}, got {match.group(1)!r}"
    if "is not Optional" in first:
        return "must not be null"
    return first
