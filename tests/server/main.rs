//! The server (`mesobake-server`) on SQLite and PostgreSQL: the API, jobs, limits, reliability
//! under kills and load, the web page in a browser, and the real binary on its defaults. One test
//! binary per crate under test, so that the suite links few; one module per subject.

#[path = "../common/binary_server.rs"]
mod binary_server;
#[path = "../common/server.rs"]
mod server_harness;

mod browser;
mod default_server;
mod reliability;
mod server;
mod server_jobs;
mod server_limits;
