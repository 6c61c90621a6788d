//! legwork's errors as Python exceptions, with legwork's messages (the file, the field, the
//! expectation). The classes follow the command line's exit codes: `InputError` is exit 2
//! (bad input), `CouldNotFinishError` exit 3 (a job that started from valid input failed).

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::PyErr;

create_exception!(legwork, LegworkError, PyException, "Any error legwork raises.");
create_exception!(legwork, InputError, LegworkError, "Bad input: a file, field, argument or value, named in the message (the command line's exit code 2).");
create_exception!(legwork, CouldNotFinishError, LegworkError, "A job that started from valid input could not finish: an optimizer failed, a simulation diverged, an output could not be written (exit code 3).");

pub(crate) fn input_error(message: String) -> PyErr {
    InputError::new_err(message)
}

pub(crate) fn could_not_finish(message: String) -> PyErr {
    CouldNotFinishError::new_err(message)
}
