//! render: film
