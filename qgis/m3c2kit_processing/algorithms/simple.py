"""A command with options and no special output handling: its inputs, OPTIONS, THREADS."""
from ..base import M3C2Algorithm
from ..options import threads, threads_arguments


class OptionsAlgorithm(M3C2Algorithm):
    OPTIONS = ()

    def add_options(self):
        for option in self.OPTIONS:
            self.addParameter(option.definition())
        self.addParameter(threads()[0])

    def option_arguments(self, parameters, context):
        args = []
        for option in self.OPTIONS:
            args += option.arguments(self, parameters, context)
        return args + threads_arguments(self, parameters, context)
