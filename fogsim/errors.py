"""Errors that reach the user as one clear line naming the file and the problem."""


class FogsimError(Exception):
    """Base class. The CLI prints ``str(exc)`` and exits non-zero, without a traceback."""


class InputError(FogsimError):
    """A user input (file, dataset, argument value) is missing, unreadable or malformed.

    ``source`` names the offending file (or dataset record) so messages always say which.
    """

    def __init__(self, source, problem: str):
        self.source = str(source)
        self.problem = problem
        super().__init__(f"{self.source}: {problem}")
