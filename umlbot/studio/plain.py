"""The checker's messages in words a modeller knows (the page shows them; the CLI keeps its own).

`umlbot check` speaks the model's YAML ("needs 'branches': a list of {if: …}"); a person drawing
the model in the studio thinks in steps, choices and connections. Each rule is a message of the
compiler as a template (`{name}` stands for a part that varies: it matches any text) and its plain
form, which may use those parts. `plain_message` gives the plain form of a message, or None when no
rule knows it (the page then shows the message as it is). tests/test_studio_plain.py walks every
message the compiler's source can make and checks that a rule knows it.
"""

from __future__ import annotations

import re
from functools import cache

#: (the checker's message, the plain form); the first rule that matches wins.
RULES: tuple[tuple[str, str], ...] = (
    # --- files and YAML
    ("invalid YAML: {problem}", "This file is not valid YAML here: {problem}. Fix the text of the file."),
    ("a file holds one YAML document; found a second one",
     "This file holds a second document (a line '---'): one file holds one part of the model."),
    ("document too large{rest}", "This file is too big: split it into more files."),
    ("document nested too deeply{rest}", "This file nests lists and mappings too deeply."),
    ("unknown alias '*{name}'", "'*{name}' refers to nothing: write the value out."),
    ("a mapping key must be a plain name", "A key here is not a plain name."),
    ("duplicate key {key}", "{key} is written twice here: keep one."),
    ("not a model: no {file} in this folder", "This folder holds no model: it needs {file}."),
    ("no such model folder or file", "There is no model here."),
    ("a model file is a mapping with 'components' and 'lanes'",
     "This is not a model file: a model lists its parts (components) and its activities (swimlanes)."),
    ("this is a compiled model file{rest}",
     "This is a compiled model, not one to edit: open the model's folder."),
    ("empty activity file, and the model names {count} defined nowhere: {names}",
     "This activity file is empty, and the model calls {names}, which is drawn nowhere."),
    ("empty activity file (the swimlanes defined nowhere are listed at {where})",
     "This activity file is empty, and the model calls swimlanes drawn nowhere."),
    ("empty activity file", "This activity file is empty: add a swimlane, or remove the file."),
    ("unknown key {key} in {where} (expected: {known})", "{key} means nothing here: use one of {known}."),
    # --- the model's name and settings
    ("the model's name must be a plain name{rest}", "Give the robot a name of letters, digits, _ and -."),
    ("call_timeout_s must be a number of seconds{rest}",
     "The time to wait for an answer must be a number of seconds, more than 0 and at most 3600."),
    ("{what}; it is the robot id: give the model a `name`{rest}",
     "Give the robot a name (the model's name is its id on the network): {what}."),
    # --- components, ports and links
    ("'components' is a mapping{rest}", "List the robot's parts (components) by name."),
    ("component name {name} is not a plain name{rest}",
     "Name the part {name} with letters, digits and _ only."),
    ("'{name}' is a reserved name; choose another component name",
     "'{name}' is a word umlbot keeps for itself: give this part another name."),
    ("'{name}' is a reserved name; choose another swimlane name",
     "'{name}' is a word umlbot keeps for itself: give this swimlane another name."),
    ("a component's kind is one of {kinds}", "Choose what kind of part this is: {kinds}."),
    ("component {name} has no kind ({kinds})", "Say what kind of part {name} is: {kinds}."),
    ("component {name}: expected a kind or a mapping with 'kind'", "Say what kind of part {name} is."),
    ("unknown component kind '{kind}' (known: {known}){rest}",
     "There is no kind of part '{kind}': choose one of {known}."),
    ("'ports' is a mapping: port_name: feature",
     "List this part's ports by name, each with the feature it offers."),
    ("port name {name} is not a plain name", "Name the port {name} with letters, digits and _ only."),
    ("a port names one feature of its component", "A port offers one feature of its part: choose one."),
    ("port '{port}' names unknown feature '{feature}' of {kind} component '{name}' (known: {known})",
     "{name} cannot do '{feature}' (its port {port}): choose one of {known}."),
    ("link has no '{end}' (Component.port)", "Connect this link's {end} end to a port of a part."),
    ("link '{id}' must be Component.port", "Link {id}: connect it to a port of a part (Part.port)."),
    ("'links' is a list of {rest}", "List the links, each from one part's port to another's."),
    ("a link is a mapping {rest}", "A link goes from one part's port to another's."),
    ("link '{id}' names unknown component '{name}'",
     "Link {id} goes to '{name}', which is not a part of the robot."),
    ("link '{id}' names unknown port '{port}' of component '{name}'",
     "Link {id} goes to port '{port}', which {name} does not have: add the port first."),
    # --- the deployment (which hardware each part is)
    ("the model has no deployment{rest}",
     "Say which hardware each part is (the deployment): add each part from the component library."),
    ("empty deployment", "Say which hardware each part is: the deployment is empty."),
    ("a deployment is a mapping{rest}", "Say which hardware each part is, part by part."),
    ("expected '<component>=<implementation id>'", "Write each part as Part=hardware, one a line."),
    ("component {name} deployed twice", "{name}'s hardware is said twice: keep one."),
    ("invalid deployment: {where}: {problem}", "The hardware of {where} is not right: {problem}."),
    ("deployment names unknown component '{name}'",
     "The hardware list names '{name}', which is not a part of the robot."),
    ("unknown implementation id '{impl}' for component '{name}'{rest}",
     "There is no hardware '{impl}' for {name}: choose one from the component library."),
    ("component '{name}' is {kind} but implementation '{impl}' is {other}",
     "{name} is {kind}, but the hardware '{impl}' is {other}: choose hardware of its kind."),
    ("implementation '{impl}' of '{name}' does not offer feature '{feature}'{rest}",
     "The hardware {impl} of {name} cannot do '{feature}': choose other hardware, or do not use it."),
    ("component '{name}' has no implementation in the deployment",
     "Say which hardware {name} is: pick it in the component library."),
    ("unknown driver '{driver}'{rest}", "There is no driver '{driver}' here: choose one the hardware has."),
    ("the {service} service of {names} has no driver '{driver}'{rest}",
     "{names} has no driver '{driver}': choose one it has."),
    ("'{name}' has no settings: {driver} need {needed}{rest}",
     "Give {name} its wiring ({needed}) to run it on the real robot; the simulator runs it without."),
    ("settings of '{name}' ({impl}) refused by {driver}: {problem}",
     "{name}'s wiring is not right: {problem}."),
    # --- swimlanes
    ("'lanes' is a list of swimlanes{rest}", "List the swimlanes, each with its name and its steps."),
    ("a swimlane is a mapping{rest}", "A swimlane has a name and its steps."),
    ("a swimlane needs 'lane: Name'{rest}", "Give this swimlane a name."),
    ("swimlane {name} has no 'nodes'", "Swimlane {name} has no steps: add a start and an end."),
    ("'nodes' is a list of activity nodes", "List this swimlane's steps."),
    ("duplicate swimlane '{name}' (first defined at {where})",
     "There are two swimlanes named '{name}' (the first at {where}): rename one."),
    ("swimlane '{name}' has no start node", "Swimlane {name} needs a start: add a start node."),
    ("swimlane '{name}' has no end node", "Swimlane {name} needs an end: add an end node."),
    ("duplicate start node '{id}': swimlane '{name}' already starts at '{first}'",
     "Swimlane {name} starts twice ('{first}' and '{id}'): keep one start."),
    ("virtual swimlane '{name}' is never called",
     "Nothing calls the activity {name}: call it from a step, or remove it."),
    ("'{name}' is the swimlane of component '{comp}'; only virtual swimlanes can be called",
     "'{name}' is the part {comp}'s own swimlane: it runs by itself and cannot be called."),
    ("swimlane '{name}' takes no arguments, got {n}", "Call the activity {name} without arguments."),
    ("a call of swimlane '{name}' is an action of its own; it gives no value",
     "Calling {name} is a step of its own: it gives no value to use here."),
    # --- steps (nodes)
    ("an activity node is a mapping{rest}", "A step has an id and a kind."),
    ("an activity node needs 'id'{rest}", "Give this step an id (letters, digits, _ and -)."),
    ("node {id}: 'kind' must be one of {kinds}", "Choose what step {id} is: {kinds}."),
    ("duplicate node id '{id}' in swimlane '{name}'", "Two steps of {name} are called '{id}': rename one."),
    ("{what} has no outgoing flow: give it 'next' or put a node after it",
     "Connect this step to the next one ({what} leads nowhere)."),
    ("{what} needs 'branches': {rest}",
     "This choice needs at least two ways out: connect it to the next steps."),
    ("{what} needs 'targets': a list of node ids", "Connect this fork to the steps that run side by side."),
    ("{what} needs at least two targets",
     "A fork splits the flow in two or more: connect it to one more step."),
    ("'{key}' of {what} must be a single value", "Write one value for {key} of {what}."),
    ("'{key}' of {what} must be a plain name, got {text}", "{key} of {what} must name a step, not {text}."),
    ("{what} needs '{key}'", "Fill in {key} of {what}."),
    ("a decision output is {rest}", "Each way out of a choice has a condition, or is the 'else' way."),
    ("unknown key '{key}' in decision output (expected: if, then, else)",
     "'{key}' means nothing on a way out of a choice: give it a condition and the step it leads to."),
    ("an else output has no guard: write {rest}",
     "The 'else' way has no condition: it is taken when no other holds."),
    ("decision has two else outputs (the first at line {line})",
     "This choice has two 'else' ways (the first at line {line}): give one a condition."),
    ("decision output without guard: write {rest}",
     "Give this way out of the choice a condition, or make it the 'else' way."),
    ("a guard is an expression", "A condition is a test such as distance < 30."),
    ("decision '{id}' has no else output: when no guard holds, this flow stops",
     "Choice {id} has no 'else' way: when no condition holds, the robot stops here. Add one."),
    ("flow from '{source}' goes to unknown node '{target}'",
     "The step after '{source}' is '{target}', which does not exist."),
    ("the start node '{id}' cannot have incoming flows (from '{sources}')",
     "Nothing may lead back into the start '{id}' (from '{sources}'): connect it to another step."),
    ("node '{id}' has no path from the start of swimlane '{name}'",
     "Step '{id}' is never reached: connect a step of {name} to it."),
    ("fork '{id}' has no matching join: {why}",
     "The side-by-side steps of fork '{id}' never meet again at a join: {why}."),
    ("join '{id}' is the matching join of two forks ('{a}' and '{b}')",
     "Join '{id}' closes two forks ('{a}' and '{b}'): give each its own join."),
    ("join '{id}' can never fire: {why}", "Join '{id}' waits for flows that never all arrive: {why}."),
    ("join '{id}' has one incoming flow and no fork; it does nothing",
     "Join '{id}' joins nothing: remove it."),
    ("an action is a call: {rest}",
     "A step does one thing: call a part's feature (Part.feature(…)), an activity, or wait (msleep(ms))."),
    # --- expressions (calls, conditions, values)
    ("unknown component '{name}'", "'{name}' is not a part of the robot."),
    ("unknown feature '{feature}' of {kind} component '{name}' (known: {known})",
     "{name} cannot do '{feature}': it can {known}."),
    ("implementation '{impl}' of '{name}' does not offer feature '{feature}' (it offers: {known})",
     "The hardware {impl} of {name} cannot do '{feature}': it can {known}."),
    ("{call} takes {n} argument(s) ({params}), got {got}",
     "{call} takes {n} value(s) ({params}), not {got}."),
    ("{call} takes 1 argument ({params}), got {got}", "{call} takes one value ({params}), not {got}."),
    ("argument {i} ({name}) of {comp}.{feature} must be {range}, got {got}",
     "{name} of {comp}.{feature} must be {range}, not {got}."),
    ("{call} needs an argument: {example}", "{call} needs a value: {example}."),
    ("{call} needs a number of {unit}, got {got}", "{call} needs a number of {unit}, not {got}."),
    ("{call} needs a duration of 0 or more, got {got}", "{call} needs a time of 0 or more, not {got}."),
    ("Application.exit takes no arguments", "Application.exit ends the program: write it without values."),
    ("unknown builtin 'Application.{name}'{rest}", "There is no Application.{name}: only Application.exit."),
    ("unknown datastore '{name}' in swimlane '{lane}'{rest}",
     "'{name}' is no stored value of swimlane {lane}: store it first (a datastore step)."),
    ("'{name}' is a component; call one of its features: {rest}",
     "'{name}' is a part: use one of its features, {name}.feature(…)."),
    ("'{name}' is a virtual swimlane, not a component; call it as {call}",
     "'{name}' is an activity: call it as {call}."),
    ("'{text}' gives no value", "'{text}' gives no value to use here."),
    ("a guard must be a bool, got {got}", "A condition must be true or false; this gives {got}."),
    ("'not' needs a bool, got {got}", "'not' needs true or false, not {got}."),
    ("'{op}' needs bools, got {a} and {b}", "'{op}' joins two tests (true or false), not {a} and {b}."),
    ("'{op}' needs numbers, got {a} and {b}", "'{op}' works on numbers, not {a} and {b}."),
    ("'-' needs a number, got {got}", "'-' works on a number, not {got}."),
    ("'{op}' needs two numbers or two strings, got {a} and {b}",
     "'{op}' compares two numbers or two texts, not {a} and {b}."),
    ("'{op}' compares values, but one side gives no value", "One side of '{op}' gives no value to compare."),
    ("comparisons cannot be chained; combine them with 'and'",
     "Write two tests joined by 'and' (a < b and b < c)."),
    ("'{text}' has too many parts: {rest}",
     "'{text}' has too many dots: write name, Lane.name or Part.feature(…)."),
    ("expression too long{rest}", "This is too long: split it over steps with stored values."),
    ("expression nested too deeply{rest}", "This nests too deeply: split it over steps with stored values."),
    ("expression tree too high{rest}",
     "This is too long a chain of operations: split it over steps with stored values."),
    ("empty expression", "Write something here."),
    ("unexpected character {char}{rest}", "The character {char} does not belong here."),
    ("string not closed", "A text in quotes is not closed: add the closing quote."),
    ("unknown escape '\\{char}' in string",
     "'\\{char}' is not a known escape in a text: write \\\\ for a backslash."),
    ("invalid number {text}", "{text} is not a number."),
    ("number too long", "This number is too long."),
    ("expected {what}, found {found}", "Write {what} here (there is {found})."),
    ("{expected}, found {found}", "{expected} (there is {found})."),
)

_SLOT = re.compile(r"\{([a-z_]+)\}")


def _pattern(template: str) -> re.Pattern[str]:
    parts: list[str] = []
    at = 0
    seen: set[str] = set()
    for m in _SLOT.finditer(template):
        parts.append(re.escape(template[at:m.start()]))
        name = m.group(1)
        if name in seen:
            parts.append(f"(?P={name})")
        else:
            parts.append(f"(?P<{name}>.*)" if name == "rest" else f"(?P<{name}>.+?)")
        seen.add(name)
        at = m.end()
    parts.append(re.escape(template[at:]))
    return re.compile("".join(parts) + r"\Z", re.DOTALL)


@cache
def _compiled() -> tuple[tuple[re.Pattern[str], str], ...]:
    return tuple((_pattern(message), plain) for message, plain in RULES)


def _fill(plain: str, parts: dict[str, str]) -> str:
    return _SLOT.sub(lambda s: parts.get(s.group(1), s.group(0)), plain)


def plain_message(message: str) -> str | None:
    """The plain form of the checker's `message`, or None when no rule knows it."""
    for pattern, plain in _compiled():
        m = pattern.match(message)
        if m is not None:
            return _fill(plain, m.groupdict())
    return None
