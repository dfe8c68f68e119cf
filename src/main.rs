fn main() {
    println!("septa");
}
