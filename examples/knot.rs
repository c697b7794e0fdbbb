//! Prints the torus knot mesh of scenes/part7.toml:
//! `cargo run --release --example knot > scenes/knot.obj`. The test
//! `knot_obj_is_the_generator_output` keeps the committed file equal to this output.

fn main() {
    print!("{}", raypack::scene::obj::part7_knot_obj());
}
