"""The rosapi services over the bridge's own graph (rosbridge.md §2.2, §6.7).

Topics, types, services, nodes, publishers/subscribers, message details from the definition
tables, ROS time, and a parameter store whose values are JSON text (an unset parameter reads
``"null"``, as rosapi does). ROS 2 adds ``/rosapi/get_ros_version``.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

from davinci_sim.bridge.rosbridge.convert import typedefs
from davinci_sim.bridge.rosbridge.core import BRIDGE_NODE, ServiceFailure

if TYPE_CHECKING:
    from davinci_sim.bridge.rosbridge.core import Bridge

ROSAPI_NODE = "/rosapi"
DISTRO = {1: "noetic", 2: "humble"}
"""What ``get_ros_version`` and the ``/rosdistro`` parameter claim for each dialect."""


class RosapiNode:
    """Attach to a bridge to serve ``/rosapi/*``."""

    def attach(self, bridge: Bridge) -> None:
        self.bridge = bridge
        v = bridge.dialect.ros_version
        bridge.params.setdefault("/rosdistro", json.dumps(DISTRO[v]))
        bridge.params.setdefault("/rosversion", json.dumps("1.16.0" if v == 1 else "2"))
        services = {
            "topics": ("rosapi/Topics", self._topics),
            "topics_for_type": ("rosapi/TopicsForType", self._topics_for_type),
            "topic_type": ("rosapi/TopicType", self._topic_type),
            "services": ("rosapi/Services", self._services),
            "services_for_type": ("rosapi/ServicesForType", self._services_for_type),
            "service_type": ("rosapi/ServiceType", self._service_type),
            "service_providers": ("rosapi/ServiceProviders", self._service_providers),
            "service_node": ("rosapi/ServiceNode", self._service_node),
            "publishers": ("rosapi/Publishers", self._publishers),
            "subscribers": ("rosapi/Subscribers", self._subscribers),
            "nodes": ("rosapi/Nodes", self._nodes),
            "node_details": ("rosapi/NodeDetails", self._node_details),
            "action_servers": ("rosapi/GetActionServers", self._action_servers),
            "get_time": ("rosapi/GetTime", self._get_time),
            "get_param": ("rosapi/GetParam", self._get_param),
            "set_param": ("rosapi/SetParam", self._set_param),
            "delete_param": ("rosapi/DeleteParam", self._delete_param),
            "has_param": ("rosapi/HasParam", self._has_param),
            "get_param_names": ("rosapi/GetParamNames", self._get_param_names),
            "message_details": ("rosapi/MessageDetails", self._message_details),
            "service_request_details": ("rosapi/ServiceRequestDetails", self._request_details),
            "service_response_details": ("rosapi/ServiceResponseDetails", self._response_details),
        }
        if v == 2:
            services["get_ros_version"] = ("rosapi/GetROSVersion", self._get_ros_version)
        for name, (type_name, handler) in services.items():
            bridge.provide_service(f"/rosapi/{name}", type_name, handler, node=ROSAPI_NODE)

    async def detach(self) -> None:
        self.bridge.remove_node(ROSAPI_NODE)

    # ------------------------------------------------------------------ graph
    def _node_of(self, key) -> str:
        return key if isinstance(key, str) else BRIDGE_NODE

    async def _topics(self, req, session) -> dict:
        b = self.bridge
        names = sorted(b.topics)
        return {"topics": names, "types": [b.topic_type(n) for n in names]}

    async def _topics_for_type(self, req, session) -> dict:
        b = self.bridge
        try:
            wanted = b.registry.message(req["type"]).name
        except (KeyError, ValueError):
            return {"topics": []}
        return {"topics": sorted(n for n, t in b.topics.items() if t.type == wanted)}

    async def _topic_type(self, req, session) -> dict:
        return {"type": self.bridge.topic_type(req["topic"])}

    async def _services(self, req, session) -> dict:
        return {"services": sorted(self.bridge.services)}

    async def _services_for_type(self, req, session) -> dict:
        b = self.bridge
        try:
            wanted = b.registry.service(req["type"]).name
        except (KeyError, ValueError):
            return {"services": []}
        return {"services": sorted(n for n, s in b.services.items() if s.type == wanted)}

    async def _service_type(self, req, session) -> dict:
        entry = self.bridge.services.get(req["service"])
        return {"type": self.bridge.registry.wire_name(entry.type, "srv") if entry else ""}

    async def _service_providers(self, req, session) -> dict:
        entry = self.bridge.services.get(req["service"])
        return {"providers": [entry.node] if entry else []}

    async def _service_node(self, req, session) -> dict:
        entry = self.bridge.services.get(req["service"])
        return {"node": entry.node if entry else ""}

    async def _publishers(self, req, session) -> dict:
        topic = self.bridge.topics.get(req["topic"])
        nodes = {self._node_of(k) for k in topic.publishers} if topic else set()
        return {"publishers": sorted(nodes)}

    async def _subscribers(self, req, session) -> dict:
        topic = self.bridge.topics.get(req["topic"])
        nodes: set[str] = set()
        if topic:
            nodes |= {n for n, _ in topic.listeners}
            if topic.subscriptions:
                nodes.add(BRIDGE_NODE)
        return {"subscribers": sorted(nodes)}

    async def _nodes(self, req, session) -> dict:
        return {"nodes": sorted(self.bridge.nodes)}

    async def _node_details(self, req, session) -> dict:
        b, node = self.bridge, req["node"]
        pubs = sorted(
            n for n, t in b.topics.items() if any(self._node_of(k) == node for k in t.publishers)
        )
        subs = sorted(
            n
            for n, t in b.topics.items()
            if any(x == node for x, _ in t.listeners) or (node == BRIDGE_NODE and t.subscriptions)
        )
        srvs = sorted(n for n, s in b.services.items() if s.node == node)
        return {"subscribing": subs, "publishing": pubs, "services": srvs}

    async def _action_servers(self, req, session) -> dict:
        return {"action_servers": sorted(self.bridge.actions)}

    async def _get_time(self, req, session) -> dict:
        return {"time": self.bridge.dialect.stamp(self.bridge.now())}

    async def _get_ros_version(self, req, session) -> dict:
        v = self.bridge.dialect.ros_version
        return {"version": v, "distro": DISTRO[v]}

    # ------------------------------------------------------------------ parameters
    async def _get_param(self, req, session) -> dict:
        default = req.get("default", req.get("default_value", ""))
        value = self.bridge.params.get(req["name"])
        if value is None:
            value = default if default else "null"
        return {"value": value}

    async def _set_param(self, req, session) -> dict:
        try:
            json.loads(req["value"])
        except ValueError as e:
            raise ServiceFailure(f"set_param: value must be JSON text ({e})") from None
        self.bridge.params[req["name"]] = req["value"]
        return {}

    async def _delete_param(self, req, session) -> dict:
        self.bridge.params.pop(req["name"], None)
        return {}

    async def _has_param(self, req, session) -> dict:
        return {"exists": req["name"] in self.bridge.params}

    async def _get_param_names(self, req, session) -> dict:
        return {"names": sorted(self.bridge.params)}

    # ------------------------------------------------------------------ types
    async def _message_details(self, req, session) -> dict:
        try:
            spec = self.bridge.registry.message(req["type"])
        except (KeyError, ValueError) as e:
            raise ServiceFailure(str(e)) from None
        return {"typedefs": typedefs(self.bridge.registry, spec)}

    async def _request_details(self, req, session) -> dict:
        try:
            spec = self.bridge.registry.service(req["type"]).request
        except (KeyError, ValueError) as e:
            raise ServiceFailure(str(e)) from None
        return {"typedefs": typedefs(self.bridge.registry, spec)}

    async def _response_details(self, req, session) -> dict:
        try:
            spec = self.bridge.registry.service(req["type"]).response
        except (KeyError, ValueError) as e:
            raise ServiceFailure(str(e)) from None
        return {"typedefs": typedefs(self.bridge.registry, spec)}
