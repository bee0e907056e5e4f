// The engine's routes for double ("float64"): op_route<double, Op> for every
// registered operation (engine_impl.hpp), compiled apart from the other dtype's.
#include "engine_impl.hpp"

template void rbd::engine_detail::add_routes<double>(rbd::engine_detail::OpRoute<double>*);
