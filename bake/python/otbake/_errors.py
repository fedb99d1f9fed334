"""The exceptions of otbake. Every error the native module raises is one of these, and its
message is the Rust library's (naming the argument, file or field, and the fix)."""


class Error(Exception):
    """Base class of every otbake error."""


class ArgumentError(Error, ValueError):
    """An argument has the wrong type, shape, dtype or memory layout (it names the argument)."""


class QueryError(Error, ValueError):
    """The runtime refused a query: weights, kernel, coordinates or indices (it names which)."""


class ArchiveError(Error):
    """Archive bytes or files were refused (unreadable, truncated, corrupt, of another format)."""


class ManifestError(Error):
    """A manifest could not be read or is invalid (the message gives file:line:column)."""


class BakeError(Error):
    """A bake failed. ``report`` holds the bake report (a dict) when the bake ran."""

    def __init__(self, message, report=None):
        super().__init__(message)
        self.report = report
