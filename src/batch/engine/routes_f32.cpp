// The engine's routes for float ("float32"): op_route<float, Op> for every
// registered operation (engine_impl.hpp), compiled apart from the other dtype's.
#include "engine_impl.hpp"

template void rbd::engine_detail::add_routes<float>(rbd::engine_detail::OpRoute<float>*);
