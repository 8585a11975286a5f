"""What the errors do: first-order shares and exact bounds, the nonlinear virtual prototype, certified
bounds, global worst cases over regions (interval enclosures), synthesis, statistics, maps and the design
comparison."""
