"""Service guards: no request to a node's services can raise into its executor.

:func:`guard_services` makes every service of a node answer (a refusal with the reason,
naming the parameter it is about) instead of raising into the executor, which would stop the
node.
"""
from __future__ import annotations


def _refusal(request, response, reason):
    """Fill ``response`` as a refusal of ``request`` (every service type the node offers)."""
    from rcl_interfaces.msg import SetParametersResult
    if hasattr(response, 'results') and hasattr(request, 'parameters'):   # SetParameters
        response.results = [SetParametersResult(successful=False, reason=reason)
                            for _ in request.parameters]
    elif hasattr(response, 'result') and hasattr(request, 'parameters'):   # ...Atomically
        response.result = SetParametersResult(successful=False, reason=reason)
    elif hasattr(response, 'success') and hasattr(response, 'message'):   # SetBool, Trigger
        response.success, response.message = False, reason
    return response


def _unreadable(parameter_msg):
    """Why an ``rcl_interfaces/Parameter`` message cannot be read ('' if it can)."""
    from rclpy.parameter import Parameter
    try:
        Parameter.from_parameter_msg(parameter_msg)
    except Exception as exc:   # e.g. a type number that is no Parameter.Type
        return f'{parameter_msg.name}: refused: {type(exc).__name__}: {exc}'
    return ''


def _naming(node, parameter_msgs, reason):
    """``reason`` for refusing ``parameter_msgs``, prefixed with the names it is about when it
    names none of them (rclpy's own refusals: "Wrong parameter type...", "Static parameter
    cannot be undeclared", "Invalid access to undeclared parameter(s): []")."""
    names = [p.name for p in parameter_msgs]
    if any(name and name in reason for name in names):
        return reason
    undeclared = [p.name for p in parameter_msgs if not node.has_parameter(p.name)]
    unset = [p.name for p in parameter_msgs if p.value.type == 0]
    clash = []
    for p in parameter_msgs:
        if p.name in undeclared or p.value.type == 0:
            continue
        descriptor = node.describe_parameter(p.name)
        if not descriptor.dynamic_typing and p.value.type != descriptor.type:
            clash.append(p.name)
    culprits = (undeclared if 'undeclared parameter' in reason else
                unset if 'undeclared' in reason else
                clash if 'type' in reason else []) or names
    return f"{', '.join(culprits)}: {reason}"


def guard_services(node, log):
    """Wrap every service callback of ``node`` so that no request can raise into the executor.

    A callback that raises or returns something other than its response type answers a
    refusal naming the error instead, and ``log(message)`` is told. Parameter requests are
    answered per parameter as ROS 2 specifies them, and every refusal names its parameter:
    ``SetParameters`` (each parameter on its own) sets each readable parameter through the
    callback one at a time, so one that cannot be read (a type number that is no
    ``Parameter.Type``, such as 200) is refused alone, not with the ones before it that were
    already applied; ``SetParametersAtomically`` refuses the whole request, naming the
    parameter at fault.
    """
    for srv in node.services:
        if getattr(srv.callback, '_guarded', False):
            continue
        original, response_type, name = srv.callback, srv.srv_type.Response, srv.srv_name
        request_type = srv.srv_type.Request

        def call(cb, request, _type, _name):
            try:
                out = cb(request, _type())
                if isinstance(out, _type):
                    return out
                reason = f'internal error: the callback returned {type(out).__name__}'
            except Exception as exc:   # any request must get an answer, never stop the node
                reason = f'refused: {type(exc).__name__}: {exc}'
            log(f'service {_name}: {reason}')
            return _refusal(request, _type(), reason)

        def guarded(request, response, _cb=original, _type=response_type, _name=name,
                    _request=request_type):
            parameters = getattr(request, 'parameters', None)
            if parameters is None:
                return call(_cb, request, _type, _name)
            if hasattr(response, 'results'):   # SetParameters: one at a time
                results = []
                for prm in parameters:
                    problem = _unreadable(prm)
                    if problem:
                        results.append(_refusal(_request(parameters=[prm]), _type(),
                                                problem).results[0])
                        continue
                    out = call(_cb, _request(parameters=[prm]), _type, _name)
                    result = (out.results[0] if len(out.results) == 1 else _refusal(
                        _request(parameters=[prm]), _type(),
                        'internal error: no result').results[0])
                    if not result.successful:
                        result.reason = _naming(node, [prm], result.reason)
                    results.append(result)
                response.results = results
                return response
            problem = next(filter(None, map(_unreadable, parameters)), '')
            if problem:   # atomic: nothing is applied
                return _refusal(request, _type(), problem)
            out = call(_cb, request, _type, _name)
            if hasattr(out, 'result') and not out.result.successful:
                out.result.reason = _naming(node, parameters, out.result.reason)
            return out

        guarded._guarded = True
        srv.callback = guarded


__all__ = ['guard_services']
