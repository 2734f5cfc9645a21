"""The application: the command line, the run of a case, its report and its output."""
