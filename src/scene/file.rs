//! TOML scene files (documented key by key in scenes/README.md).
