//! The penalty contact model (eqs. 33–41): being written.
